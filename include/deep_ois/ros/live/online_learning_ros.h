// The compensation nodelet's online self-calibration (core/online/online_stabiliser_learner.h) in
// ROS terms: the learner made at the first pair (when the camera is known, so its stored model can
// be found), the model in use handed to the StabiliserFlowCompensator when the learner swaps it
// (said once), the pairs handed over with their frames (shared, not copied: the callbacks never
// track or fit), the per-pair checks published on `compensation_check`, and /diagnostics.
//
// Each camera's learned model is kept in a file under ~learning_dir ($ROS_HOME/deep_ois/stabilisers)
// named by ~learning_key or the stream (frame id, size, focal length), written atomically by the
// learner, and loaded at the next start as the model in use (the ~model file stays a candidate).
//
// With ~online_calibration, the learner's tracked pairs also feed the online camera-IMU calibration
// (OnlineCalibrationRos: `online_calibration`, its file beside the learned model's).
#pragma once

#include <deep_ois/GyroFlow.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <deque>
#include <functional>
#include <optional>
#include <memory>
#include <mutex>
#include <string>

#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/ros/live/compensation_parameters.h"
#include "deep_ois/ros/live/live_diagnostics.h"
#include "deep_ois/ros/live/online_calibration_ros.h"
#include "deep_ois/ros/live/stabiliser_flow_compensator.h"

namespace deep_ois {

// The learned model's file for a camera: `key` when not empty, else made from the frame id, size
// and focal length; characters other than [A-Za-z0-9_.-] become '_'. `dir` empty: ROS_HOME's.
std::string learnedModelPath(const std::string& dir, const std::string& key, const GyroFlow& gyro);

class OnlineLearningRos {
 public:
  // `shipped`: the ~model file (a candidate, and the model in use when this camera has none stored).
  // `on_check_subscribers`: called when a subscriber to compensation_check connects or leaves (the
  // compensation's lazy subscription counts it as an output).
  OnlineLearningRos(ros::NodeHandle nh, const CompensationParameters& params, StabiliserModelFile shipped,
                    LiveDiagnostics& diagnostics, const std::string& log_name,
                    std::function<void()> on_check_subscribers = {});
  ~OnlineLearningRos();
  OnlineLearningRos(const OnlineLearningRos&) = delete;
  OnlineLearningRos& operator=(const OnlineLearningRos&) = delete;

  // Whether compensation_check has a subscriber.
  bool checksWanted() const { return check_pub_.getNumSubscribers() > 0; }

  // Before a pair is compensated: the learner exists for the stream's camera and the compensator
  // uses the model in use (a swap is said once). Never blocks on a fit.
  void beforePair(const GyroFlow& gyro, StabiliserFlowCompensator& compensator);
  // After: hands the pair to the learner (dropped and counted when it is busy), publishes the
  // checks made since, updates /diagnostics. `gyro_homographies`: the plain gyro's per patch.
  // `tracks`: the pair's tracks when the caller made them (the fusion), handed to the learner
  // instead of the frames being tracked again. A fused pair is checked on its prior (the model's).
  void afterPair(const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a,
                 const sensor_msgs::ImageConstPtr& image_b, const StabiliserFlowResult& result,
                 const std::vector<Eigen::Matrix3d>& gyro_homographies,
                 const std::vector<FeatureMatch>* tracks = nullptr);
  // The median model residual of the last usable per-pair checks (up to kRecentChecks), pixels:
  // the fusion's prior sigma. None before the first.
  std::optional<double> recentModelResidualPx() const;
  static constexpr std::size_t kRecentChecks = 10;
  // Whether the plain gyro should be published instead of the model (~fallback_to_gyro and the
  // checks' hysteresis).
  bool fallingBack() const;
  void timeWentBack();
  void setLearning(bool on, double cpu_share);
  // For the benchmark: waits until the learner has nothing queued and no fit running.
  bool waitIdle(double timeout_s);
  const OnlineStabiliserLearner* learner() const { return learner_.get(); }

 private:
  void startFor(const GyroFlow& gyro);
  void updateDiagnostics();         // with mutex_ held
  bool fallingBackLocked() const;  // with mutex_ held

  // The pair callbacks and the /diagnostics timer run on the manager's worker threads: one lock
  // for the learner (made anew per camera) and the counts said in the log.
  mutable std::mutex mutex_;
  ros::WallTimer diagnostics_timer_;

  ros::NodeHandle nh_;
  CompensationParameters params_;
  StabiliserModelFile shipped_;
  LiveDiagnostics& diagnostics_;
  std::string log_name_;
  ros::Publisher check_pub_;
  // Before learner_: the learner's tracking thread calls into it until the learner is destroyed.
  std::unique_ptr<OnlineCalibrationRos> calibration_;
  std::unique_ptr<OnlineStabiliserLearner> learner_;
  std::string model_path_;
  std::string frame_id_;
  std::uint64_t version_in_use_ = 0;
  std::size_t pairs_ = 0;
  std::deque<double> recent_model_residuals_px_;  // usable checks' model residuals, newest last
  std::size_t untrackable_ = 0;  // frames of an encoding the tracker cannot read (counted)
  // The learner's verdicts and replayed data already said in the log (each said once).
  std::size_t verdicts_logged_ = 0;
  std::size_t repeated_logged_ = 0, kept_at_repeated_log_ = 0;
};

}  // namespace deep_ois
