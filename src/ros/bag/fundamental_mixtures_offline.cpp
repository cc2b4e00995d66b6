#include "deep_ois/ros/bag/fundamental_mixtures_offline.h"

#include <deep_ois/TrainingPair.h>
#include <ros/package.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <chrono>
#include <memory>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "deep_ois/core/ground_truth/fundamental_mixtures_ground_truth.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/bag_recovery.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
namespace {


// Everything one bag needs for its pairs besides the images.
struct BagContext {
  const std::string& path;
  const BagSequence& sequence;
  const ImuSampleBuffer& imu;
  RollingShutterConfig rolling_shutter;
  const FundamentalMixturesGroundTruth& ground_truth;
};

// A failure of the output bag, kept apart from the input errors: it ends the job.
struct OutputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

void reject(TrainingPair& msg, const std::string& key, const std::string& reason,
            FundamentalMixturesSummary& summary) {
  msg.accepted = false;
  msg.rejection_reason = reason;
  msg.model = toString(MotionModel::kNone);
  ++summary.rejected;
  ++summary.rejections[key];
}

// One record: the gyro input, then the tracks and the solver's target.
TrainingPair processPair(const BagContext& bag, const BagFrame& a, const BagFrame& b,
                         const FundamentalMixturesOfflineOptions& options,
                         FundamentalMixturesSummary& summary) {
  const CameraModel& camera = *bag.sequence.camera;
  TrainingPair msg;
  msg.header.stamp = b.stamp;
  msg.header.frame_id =
      options.gyro.camera_frame_id.empty() ? b.frame_id : options.gyro.camera_frame_id;
  msg.previous_stamp = a.stamp;
  msg.source_bag = bag.path;
  msg.image_width = camera.width();
  msg.image_height = camera.height();
  matrixToRowMajor(camera.K(), msg.K.data());
  msg.distortion_model = bag.sequence.distortion_model;
  if (camera.hasDistortion()) {
    msg.D.assign(camera.distortion().data(),
                 camera.distortion().data() + camera.distortion().size());
  }
  msg.patch_count = bag.rolling_shutter.patch_count;

  // The nodelet does not pair frames this far apart (frames dropped upstream); neither do we.
  const double interval_s = (b.stamp - a.stamp).toSec();
  if (!(interval_s > 0.0) || interval_s > options.gyro.max_frame_interval_s) {
    reject(msg, "frame_interval",
           "frames: interval " + std::to_string(interval_s) +
               " s is outside (0, max_frame_interval = " +
               std::to_string(options.gyro.max_frame_interval_s) + " s]",
           summary);
    return msg;
  }

  // Exactly the gyro flow nodelet's computation (and evaluate's): same parameters, same buffer
  // rules.
  const RollingShutterHomographies gyro = computeRollingShutterHomographies(
      bag.imu, options.gyro.integration, bag.rolling_shutter, camera.K(),
      bag.sequence.secondsSinceBase(a.stamp), bag.sequence.secondsSinceBase(b.stamp));
  if (!gyro.ok()) {
    reject(msg, std::string("gyro: ") + toString(gyro.status), "gyro: " + gyro.reason, summary);
    return msg;
  }
  msg.gyro_homographies = flattenMatrices(gyro.homographies);

  // The evaluator's ground-truth rows run this same code (fundamental_mixtures_ground_truth.h).
  const std::vector<FeatureMatch> matches = bag.ground_truth.track(a.gray, b.gray);
  msg.match_count = matches.size();
  const FundamentalMixturesResult result =
      bag.ground_truth.solve(matches, camera,
                             options.global_fundamental ? GroundTruthModel::kGlobalFundamental
                                                        : GroundTruthModel::kFundamentalMixtures);
  msg.inlier_count = result.inlier_count;
  msg.patch_inlier_counts.assign(result.inlier_counts.begin(), result.inlier_counts.end());
  if (!result.ok()) {
    reject(msg, toString(result.status), result.reason, summary);
    return msg;
  }
  msg.accepted = true;
  msg.model = toString(result.model);
  msg.target_homographies = flattenMatrices(result.homographies);
  msg.residual_px = result.median_rotation_residual_px;
  ++summary.accepted;
  return msg;
}

// Streams one input bag into `output`. Throws std::runtime_error naming the bag; records written
// before the error stay in `output`. A corrupt chunk part-way through costs only the pairs from
// there on: the pairs before it are computed from what could be read (a pair whose IMU samples
// lay in the corrupt chunk is written as rejected by the gyro), then the error is thrown.
// A bag without a valid index (cut short, or its writer killed) is read from its repaired copy
// (`input`): every message before the damage.
void processBag(const ReadableBag& input, const FundamentalMixturesOfflineOptions& options,
                rosbag::Bag& output, FundamentalMixturesSummary& summary,
                const std::atomic<bool>* stop) {
  const std::string& path = input.originalPath();
  const BagSequence sequence =
      readBagSequence(input.path(), options.topics, BagReadFailure::kKeepPrefix);
  // Without IMU messages no pair has a gyro input: say so (not "no transform", its consequence).
  if (!sequence.imu_problem.empty()) throw std::runtime_error(path + ": " + sequence.imu_problem);
  RollingShutterConfig rs = options.gyro.rolling_shutter;
  if (options.gyro.rotation_from_tf) {
    if (!sequence.imu_to_camera_rotation) {
      throw std::runtime_error(path + ": " + sequence.imu_to_camera_problem +
                               " (set imu_to_camera_rotation in the gyro flow config to override)");
    }
    rs.imu_to_camera_rotation = *sequence.imu_to_camera_rotation;
  }
  const ImuSampleBuffer imu = sequence.imuBuffer();
  const FundamentalMixturesGroundTruth ground_truth(options.corners, options.klt, options.solver);
  const BagContext context{path, sequence, imu, rs, ground_truth};
  const cv::Size camera_size(sequence.camera->width(), sequence.camera->height());

  BagFrameReader reader(input.path(), options.topics.image);
  BagFrame previous, current;
  if (!reader.next(previous)) return;
  while (!(stop && stop->load()) && reader.next(current)) {
    if (current.gray.size() != camera_size || previous.gray.size() != camera_size) {
      throw std::runtime_error(path + ": frame " + std::to_string(reader.framesRead()) + " is " +
                               std::to_string(current.gray.cols) + "x" +
                               std::to_string(current.gray.rows) + " but camera_info says " +
                               std::to_string(camera_size.width) + "x" +
                               std::to_string(camera_size.height));
    }
    const TrainingPair msg = processPair(context, previous, current, options, summary);
    try {
      output.write(options.output_topic, msg.header.stamp, msg);
    } catch (const rosbag::BagException& e) {
      throw OutputError(options.output_path + ": cannot write the output bag: " + e.what());
    }
    ++summary.pairs_done;
    if (options.on_progress) options.on_progress(summary.pairs_done, summary.pairs_total);
    std::swap(previous, current);
  }
  // The images may all be readable while the IMU or camera_info stream was not.
  if (!sequence.read_error.empty()) throw std::runtime_error(input.originalNames(sequence.read_error));
}

}  // namespace

std::string FundamentalMixturesOfflineOptions::validate() const {
  if (bags.empty()) return "bags: at least one input bag is needed";
  for (const std::string& bag : bags) {
    if (bag == output_path) return "output: '" + output_path + "' is also an input bag";
  }
  if (output_path.empty()) return "output: the output bag path is empty";
  if (output_topic.empty()) return "output_topic is empty";
  if (topics.image.empty() || topics.camera_info.empty() || topics.imu.empty()) {
    return "image, camera_info and imu topics must not be empty";
  }
  std::string problem = gyro.rolling_shutter.validate();
  if (!problem.empty()) return "gyro flow parameters: " + problem;
  if (!(problem = corners.validate()).empty()) return "corner detector: " + problem;
  if (!(problem = klt.validate()).empty()) return "KLT: " + problem;
  FundamentalMixturesOptions solver_used = solver;
  solver_used.patch_count = gyro.rolling_shutter.patch_count;
  if (!(problem = solver_used.validate()).empty()) return "Fundamental Mixtures solver: " + problem;
  return "";
}

FundamentalMixturesOfflineOptions loadFundamentalMixturesOfflineOptions(
    const ros::NodeHandle& private_nh) {
  FundamentalMixturesOfflineOptions options;
  auto fail = [&](const std::string& name, const std::string& what) {
    throw std::invalid_argument(private_nh.resolveName(name) + ": " + what);
  };
  if (!private_nh.getParam("bags", options.bags) || options.bags.empty()) {
    fail("bags", "a non-empty list of input bag paths is required");
  }
  if (!private_nh.getParam("output", options.output_path) || options.output_path.empty()) {
    fail("output", "the output bag path is required");
  }
  // Strict: a parameter set with the wrong type is an error naming it, not a silent default.
  const NodeHandleParameters source(private_nh);
  options.topics.image = source.param<std::string>("image_topic", options.topics.image);
  options.topics.camera_info = source.param<std::string>("camera_info_topic", options.topics.camera_info);
  options.topics.imu = source.param<std::string>("imu_topic", options.topics.imu);
  options.output_topic = source.param<std::string>("output_topic", options.output_topic);
  options.global_fundamental = source.param<bool>("global_fundamental", false);
  if (source.param<bool>("show_progress", true)) {
    options.on_progress = [](std::size_t done, std::size_t total) {
      ROS_INFO_THROTTLE(10.0, "fundamental_mixtures: %zu of %zu pairs", done, total);
    };
  }

  // The gyro flow nodelet's own file, so the training input matches what it publishes.
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  source.get("gyro_flow_config", gyro_config);
  if (gyro_config.empty()) fail("gyro_flow_config", "package deep_ois not found, so give the path");
  try {
    options.gyro = loadGyroFlowParameters(YamlParameters(gyro_config));
  } catch (const std::exception& e) {
    fail("gyro_flow_config", e.what());
  }
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument(private_nh.resolveName("") + ": " + problem);
  return options;
}

std::string FundamentalMixturesSummary::text() const {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof(line),
                "%zu of %zu pairs in %.1f s (%.2f pairs/s): %zu accepted, %zu rejected", pairs_done,
                pairs_total, elapsed_s, pairsPerSecond(), accepted, rejected);
  out << line << (interrupted ? " (interrupted)" : "") << "\n";
  for (const auto& [reason, count] : rejections)
    out << "  rejected, " << reason << ": " << count << "\n";
  for (const std::string& error : bag_errors) out << "  bag error: " << error << "\n";
  return out.str();
}

FundamentalMixturesOffline::FundamentalMixturesOffline(FundamentalMixturesOfflineOptions options)
    : options_(std::move(options)) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument(problem);
  // Input and target must describe the same row patches.
  options_.solver.patch_count = options_.gyro.rolling_shutter.patch_count;
}

FundamentalMixturesSummary FundamentalMixturesOffline::run(const std::atomic<bool>* stop) const {
  const auto started = std::chrono::steady_clock::now();
  FundamentalMixturesSummary summary;
  // Each input opened once, up front, for the pair count: a bag without index is repaired here
  // into a temporary copy (kept until the end of the job).
  std::vector<std::unique_ptr<ReadableBag>> inputs;
  std::vector<std::string> open_errors;
  for (const std::string& path : options_.bags) {
    try {
      inputs.push_back(std::make_unique<ReadableBag>(path));
      summary.pairs_total += indexedFramePairCount(inputs.back()->path(), options_.topics.image);
    } catch (const std::exception& e) {
      inputs.push_back(nullptr);
      open_errors.push_back(e.what());
      continue;
    }
    open_errors.emplace_back();
  }

  {
    // rosbag::Bag closes (and writes its index) in its destructor, so the output is readable
    // whatever leaves this scope: the end, the stop flag, or an exception.
    rosbag::Bag output;
    try {
      output.open(options_.output_path, rosbag::bagmode::Write);
      // One chunk per pair: rosbag flushes a chunk to the file when it closes it, so a job killed
      // outright (SIGKILL, power loss: no index written) loses at most the pair in progress, and
      // ReadableBag or `rosbag reindex` recovers every pair before it. Costs ~100 bytes per record.
      output.setChunkThreshold(0);
    } catch (const rosbag::BagException& e) {
      throw std::runtime_error(options_.output_path +
                               ": cannot create the output bag: " + e.what());
    }
    for (std::size_t k = 0; k < options_.bags.size(); ++k) {
      const std::string& path = options_.bags[k];
      if (stop && stop->load()) break;
      if (!inputs[k]) {
        summary.bag_errors.push_back(open_errors[k]);
        continue;
      }
      // What a damaged input lost is said even when every pair that remains goes through.
      if (inputs[k]->recovered()) summary.bag_errors.push_back(inputs[k]->note());
      try {
        processBag(*inputs[k], options_, output, summary, stop);
      } catch (const OutputError&) {
        throw;
      } catch (const std::exception& e) {
        // One unreadable recording must not lose the others; messages from bag readers already
        // name the file.
        const std::string what = inputs[k]->originalNames(e.what());
        summary.bag_errors.push_back(what.rfind(path, 0) == 0 ? what : path + ": " + what);
      }
    }
    output.close();
  }
  summary.interrupted = stop && stop->load();
  summary.elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return summary;
}

}  // namespace deep_ois
