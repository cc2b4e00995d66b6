// The offline Fundamental Mixtures job: reads recordings (rosbags), and for every pair of
// consecutive frames writes a deep_ois/TrainingPair with the gyro homographies (the network's
// input, computed by the gyro flow nodelet's code) and the rotation-only Fundamental Mixtures
// homographies (the training target) into one output bag. The nodelet
// deep_ois/fundamental_mixtures and the fundamental_mixtures tool are thin shells over this class.
#pragma once

#include <ros/node_handle.h>

#include <atomic>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"
#include "deep_ois/core/common/progress_callback.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"

namespace deep_ois {

struct FundamentalMixturesOfflineOptions {
  std::vector<std::string> bags;  // input recordings, processed in this order
  std::string output_path;        // the training bag; overwritten
  std::string output_topic = "/deep_ois/training_pair";
  BagSequenceTopics topics;  // image, camera_info and imu topics of the inputs
  // The gyro flow nodelet's parameters (config/gyro_flow.yaml), so that the input homographies
  // are exactly what the nodelet publishes at run time. Its patch_count also sets the solver's.
  GyroFlowParameters gyro;
  CornerDetectorOptions corners;
  KltOptions klt;
  FundamentalMixturesOptions solver;
  bool global_fundamental = false;  // the paper's ablation: one F per frame instead of mixtures
  // Called after every pair with (pairs done, pairs of all inputs); empty for silence. The
  // command-line tool draws a progress bar, the nodelet logs (~show_progress).
  ProgressCallback on_progress;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Reads the options from a private node handle: ~bags (list of paths), ~output, ~image_topic,
// ~camera_info_topic, ~imu_topic, ~output_topic, ~global_fundamental, ~show_progress and
// ~gyro_flow_config (path of a gyro flow YAML; default the package's config/gyro_flow.yaml).
// Throws std::invalid_argument naming the parameter when one is missing or invalid.
FundamentalMixturesOfflineOptions loadFundamentalMixturesOfflineOptions(
    const ros::NodeHandle& private_nh);

struct FundamentalMixturesSummary {
  std::size_t pairs_total = 0;  // frame pairs of all inputs, from the bags' indices
  std::size_t pairs_done = 0;   // records written
  std::size_t accepted = 0;
  std::size_t rejected = 0;
  // Rejections by short reason ("too_few_inliers", "gyro: gap", ...) with counts.
  std::map<std::string, std::size_t> rejections;
  std::vector<std::string> bag_errors;  // one sentence per input that failed, naming it
  double elapsed_s = 0.0;
  bool interrupted = false;  // stopped by the stop flag; the output holds every pair done

  double pairsPerSecond() const { return elapsed_s > 0.0 ? pairs_done / elapsed_s : 0.0; }
  // Multi-line human-readable summary.
  std::string text() const;
};

// Owns no ROS communication: reads and writes bags only, so it runs without a roscore.
class FundamentalMixturesOffline {
 public:
  // Throws std::invalid_argument when the options are invalid.
  explicit FundamentalMixturesOffline(FundamentalMixturesOfflineOptions options);

  // Processes every input. A bag without a valid index (cut short, or its recorder killed) is read
  // by scanning its chunks (ReadableBag): every pair before the damage is processed and what was
  // lost is reported in bag_errors. A bag that cannot be read further (missing, not a bag, a
  // corrupt chunk, no IMU transform) is reported in bag_errors, the records already written from
  // it stay, and the job goes on with the next bag. When `stop` becomes true the output is closed
  // after the current pair. The output holds one chunk per pair, so that after SIGKILL every pair
  // written is recoverable (ReadableBag, recover_bag, or `rosbag reindex`: all but the last).
  // Throws std::runtime_error naming the output bag only when it cannot be created or written.
  FundamentalMixturesSummary run(const std::atomic<bool>* stop = nullptr) const;

  const FundamentalMixturesOfflineOptions& options() const { return options_; }

 private:
  FundamentalMixturesOfflineOptions options_;
};

}  // namespace deep_ois
