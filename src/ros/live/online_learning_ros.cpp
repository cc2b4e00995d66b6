#include "deep_ois/ros/live/online_learning_ros.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <sstream>

#include <deep_ois/CompensationPairCheck.h>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/messages/message_validation.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;
constexpr double kWarnPeriodS = 2.0;

std::string rosHome() {
  if (const char* home = std::getenv("ROS_HOME")) return home;
  if (const char* home = std::getenv("HOME")) return std::string(home) + "/.ros";
  return "/tmp/.ros";
}

bool trackableEncoding(const std::string& encoding) {
  namespace enc = sensor_msgs::image_encodings;
  return encoding == enc::MONO8 || encoding == enc::MONO16 || encoding == enc::RGB8 || encoding == enc::BGR8 ||
         encoding == enc::RGBA8 || encoding == enc::BGRA8;
}

// Holds the frames' messages (their pixels) until the learner's tracking thread is done.
struct FramesAlive {
  cv_bridge::CvImageConstPtr a, b;
};

}  // namespace

std::string learnedModelPath(const std::string& dir, const std::string& key, const GyroFlow& gyro) {
  std::string name = key;
  if (name.empty()) {
    std::ostringstream made;
    made.precision(1);
    made << (gyro.header.frame_id.empty() ? "camera" : gyro.header.frame_id) << "_" << gyro.image_width << "x"
         << gyro.image_height << "_f" << std::fixed << gyro.K[0];
    name = made.str();
  }
  for (char& c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-')) c = '_';
  const std::string base = dir.empty() ? rosHome() + "/deep_ois/stabilisers" : dir;
  return base + "/" + name + ".yaml";
}

OnlineLearningRos::OnlineLearningRos(ros::NodeHandle nh, const CompensationParameters& params,
                                     StabiliserModelFile shipped, LiveDiagnostics& diagnostics,
                                     const std::string& log_name, std::function<void()> on_check_subscribers)
    : nh_(nh), params_(params), shipped_(std::move(shipped)), diagnostics_(diagnostics), log_name_(log_name) {
  ros::SubscriberStatusCallback on_subscribers;
  if (on_check_subscribers) {
    on_subscribers = [on_check_subscribers](const ros::SingleSubscriberPublisher&) { on_check_subscribers(); };
  }
  check_pub_ = nh_.advertise<CompensationPairCheck>("compensation_check", 30, on_subscribers, on_subscribers);
  diagnostics_.setValue("learning", params_.learning ? "on (waiting for the first pair)" : "off");
  if (params_.online_calibration) {
    calibration_ = std::make_unique<OnlineCalibrationRos>(nh_, params_, diagnostics_, log_name_);
  } else {
    diagnostics_.setValue("online calibration", "off (~online_calibration)");
  }
  // The learner's figures change while no pair comes (a fit ends after a bag stops or pauses):
  // refreshed on /diagnostics' own period as well as every 15 pairs, so that they are never stale.
  diagnostics_timer_ = nh_.createWallTimer(ros::WallDuration(diagnostics_.periodS()), [this](const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    updateDiagnostics();
  });
}

OnlineLearningRos::~OnlineLearningRos() { diagnostics_timer_.stop(); }

void OnlineLearningRos::startFor(const GyroFlow& gyro) {
  learner_.reset();  // its threads stop before the calibration restarts for this camera
  model_path_ = learnedModelPath(params_.learning_dir, params_.learning_key, gyro);
  frame_id_ = gyro.header.frame_id;
  std::vector<ModelCandidate> priors;
  std::string stored_problem;
  if (fs::exists(model_path_)) {
    try {
      const StabiliserModelFile stored = StabiliserModelFile::load(model_path_);
      priors.push_back({"learned before for this camera", stored.parameters});
    } catch (const std::exception& e) {
      stored_problem = e.what();
    }
  }
  priors.push_back({"the ~model file", shipped_.parameters});
  OnlineLearningOptions options;
  options.learning = params_.learning;
  options.cpu_share = params_.learning_cpu_share;
  options.tracking_width_px = params_.learning_tracking_width_px;
  options.buffer_s = params_.learning_buffer_s;
  options.held_out_s = params_.learning_held_out_s;
  options.min_training_s = params_.learning_held_out_s;
  options.refit_every_s = params_.learning_refit_every_s;
  options.linear_dynamics_rls = params_.learning_rls;
  options.rls.forgetting_per_s = params_.learning_rls_forgetting;
  options.rls.prior_lens_motions = params_.learning_rls_prior;
  options.confirmation.pairs = static_cast<std::size_t>(params_.learning_confirm_pairs);
  options.write.test_pause_s = params_.learning_test_write_pause_s;
  options.model_path = model_path_;
  if (calibration_) {
    // On the learner's tracking thread, with the tracks it made (charged to its CPU budget).
    // A camera whose model in use moves the lens: the estimator also fits a shift per frame, so
    // that what that model gets wrong is not absorbed by the time offset.
    calibration_->startFor(onlineCalibrationPath(model_path_), gyro, !isNoLensMotion(priors.front().parameters));
    OnlineCalibrationRos* calibration = calibration_.get();
    options.on_tracked_pair = [calibration](const OnlineFramePair& pair) { calibration->onTrackedPair(pair); };
  }
  options.model_file_name = "learned online for " + model_path_;
  options.camera.width = static_cast<int>(gyro.image_width);
  options.camera.height = static_cast<int>(gyro.image_height);
  options.camera.fx = gyro.K[0];
  options.camera.fy = gyro.K[4];
  options.camera.cx = gyro.K[2];
  options.camera.cy = gyro.K[5];
  options.camera.readout_time_s = gyro.readout_time;
  std::error_code ignored;
  fs::create_directories(fs::path(model_path_).parent_path(), ignored);
  // A process killed while writing leaves its partial file beside the (untouched) model file.
  const int stale = removeStalePartialFiles(model_path_);
  if (stale > 0)
    ROS_INFO_NAMED("compensation", "%s: removed %d partial file(s) beside %s left by a process killed while writing "
                   "(the file holds the last confirmed model)", log_name_.c_str(), stale, model_path_.c_str());
  ROS_DEBUG_NAMED("compensation", "%s: learning held out %.1f s, buffer %.1f s", log_name_.c_str(),
                  options.held_out_s, options.buffer_s);
  learner_ = std::make_unique<OnlineStabiliserLearner>(options, priors, 0);
  version_in_use_ = 0;
  if (!stored_problem.empty()) {
    ROS_WARN_NAMED("compensation", "%s: the learned model %s cannot be read (%s): starting from %s; it will be "
                   "replaced when a better model is learned", log_name_.c_str(), model_path_.c_str(),
                   stored_problem.c_str(), params_.model_path.c_str());
  }
  ROS_INFO_NAMED("compensation", "%s: online learning %s for this camera (%.0f %% of a core, %.0f s kept, %.0f s "
                 "held out, a fit every %.0f s of new data); model in use: %s (%s)", log_name_.c_str(),
                 params_.learning ? "on" : "off", 100.0 * options.cpu_share, options.buffer_s, options.held_out_s,
                 options.refit_every_s, priors.front().name.c_str(),
                 priors.size() > 1 ? model_path_.c_str() : params_.model_path.c_str());
  diagnostics_.setValue("learned model file", model_path_);
}

void OnlineLearningRos::beforePair(const GyroFlow& gyro, StabiliserFlowCompensator& compensator) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool new_camera = !learner_ || gyro.header.frame_id != frame_id_ ||
                          learnedModelPath(params_.learning_dir, params_.learning_key, gyro) != model_path_;
  if (new_camera) {
    startFor(gyro);
    version_in_use_ = ~std::uint64_t{0};  // the model in use is handed over below
  }
  const std::shared_ptr<const LearnedStabiliser> model = learner_->model();
  if (model->version == version_in_use_) return;
  StabiliserModelFile file = compensator.model();
  file.name = model->name;
  file.parameters = model->parameters;
  compensator.setModel(std::move(file));
  if (version_in_use_ != ~std::uint64_t{0}) {
    // Once per swap (a swap happens at most once per fit, an undo at most once per swap). A swap is
    // on trial: written only once the per-pair check confirms it.
    const bool trial = learner_->status().confirmation.rfind("on trial", 0) == 0;
    const std::string kept =
        trial ? "on trial until the per-pair check confirms it on " + std::to_string(params_.learning_confirm_pairs) +
                    " pairs (then written to " + model_path_ + ")"
              : "not written: " + model_path_ + " keeps the last confirmed model";
    ROS_INFO_NAMED("compensation", "%s: stabiliser model swapped (version %llu): %s; %s; %s", log_name_.c_str(),
                   static_cast<unsigned long long>(model->version), model->name.c_str(), model->reason.c_str(),
                   kept.c_str());
  }
  version_in_use_ = model->version;
  updateDiagnostics();
}

void OnlineLearningRos::afterPair(const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a,
                                  const sensor_msgs::ImageConstPtr& image_b, const StabiliserFlowResult& result,
                                  const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                  const std::vector<FeatureMatch>* tracks, const CompensationCheck* check) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!learner_) return;
  ++pairs_;
  if (!trackableEncoding(image_a->encoding) || !trackableEncoding(image_b->encoding)) {
    ++untrackable_;
    diagnostics_.setValue("learning: frames of an encoding it cannot track", std::to_string(untrackable_));
  } else {
    OnlineFramePair pair;
    pair.stamp_a_s = gyro.previous_stamp.toSec();
    pair.stamp_b_s = gyro.header.stamp.toSec();
    pair.timing = result.timing;
    // The rotation the gyro flow used (the feed rotates the camera-frame rates back to the IMU's).
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        pair.timing.imu_to_camera_rotation(r, c) = gyro.imu_to_camera_rotation[static_cast<std::size_t>(3 * r + c)];
    pair.camera = result.camera;
    pair.rotations = result.rotations;
    pair.gyro_homographies = gyro_homographies;
    // The check scores the model's motion: the fusion's prior when the pair was fused.
    const std::vector<Eigen::Matrix3d>& model_homographies =
        result.prior_homographies.empty() ? result.homographies : result.prior_homographies;
    pair.model_homographies = model_homographies;
    if (tracks) {  // tracked already (for the fusion): the learner does not track the frames again
      pair.matches = *tracks;
      pair.tracked = true;
      if (check) pair.check = *check;
    }
    std::string problem;
    pair.rates = readGyroFlowRates(gyro, &problem);
    auto alive = std::make_shared<FramesAlive>();
    alive->a = cv_bridge::toCvShare(image_a);
    alive->b = cv_bridge::toCvShare(image_b);
    pair.image_a = alive->a->image;
    pair.image_b = alive->b->image;
    pair.keep_alive = alive;
    // Before the submit: the tracking thread looks up the lens the compensation used for the pair.
    if (calibration_) calibration_->rememberLens(gyro, result, fallingBackLocked() || model_homographies.empty());
    if (result.fused) {
      fused_pairs_[pair.stamp_b_s] = *result.fused;
      // Checks come in pair order and a few pairs late: more than a second of pairs waiting is a
      // learner that skips them (over budget, a full queue).
      while (fused_pairs_.size() > 100) fused_pairs_.erase(fused_pairs_.begin());
    }
    learner_->submit(std::move(pair));  // a full queue drops it (counted in the status)
  }
  if (calibration_) calibration_->afterPair(gyro);
  for (const PairVerdict& verdict : learner_->takeVerdicts()) {
    if (check_pub_.getNumSubscribers() == 0) continue;
    auto msg = boost::make_shared<CompensationPairCheck>();
    msg->header.stamp.fromSec(verdict.stamp_b_s);
    msg->header.frame_id = frame_id_;
    msg->previous_stamp.fromSec(verdict.stamp_a_s);
    msg->usable = verdict.check.usable;
    msg->tracks = static_cast<std::uint32_t>(verdict.check.tracks);
    msg->inliers = static_cast<std::uint32_t>(verdict.check.inliers);
    msg->model_residual = static_cast<float>(verdict.check.model_residual_px);
    msg->gyro_residual = static_cast<float>(verdict.check.gyro_residual_px);
    msg->confidence = static_cast<float>(verdict.check.confidence);
    msg->falling_back = verdict.falling_back && params_.fallback_to_gyro;
    msg->model_version = static_cast<std::uint32_t>(version_in_use_);
    // The fusion of this pair, and none of the older ones is waiting any longer.
    const auto fused = fused_pairs_.find(verdict.stamp_b_s);
    if (fused != fused_pairs_.end()) {
      const FusedMotion& f = fused->second;
      msg->fused = true;
      msg->fusion_refined = f.refined;
      msg->fusion_mean_correction = static_cast<float>(f.mean_correction_px);
      msg->fusion_max_correction = static_cast<float>(f.max_correction_px);
      msg->fusion_prior_sigma = static_cast<float>(f.sigma_px);
      msg->fusion_prior_residual = static_cast<float>(f.prior_residual_px);
      msg->fusion_fused_residual = static_cast<float>(f.fused_residual_px);
      msg->fusion_reason = f.reason;
    }
    fused_pairs_.erase(fused_pairs_.begin(), fused_pairs_.upper_bound(verdict.stamp_b_s));
    // Checked as every output: a check that cannot be right is counted and said, not published.
    const std::string problem = compensationPairCheckProblem(*msg);
    if (!problem.empty()) {
      diagnostics_.drop("compensation_check failed validation (warned)");
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: not publishing the check of pair %.6f on %s: %s",
                              log_name_.c_str(), verdict.stamp_b_s, check_pub_.getTopic().c_str(), problem.c_str());
      continue;
    }
    check_pub_.publish(msg);
  }
  // The figures every 15 pairs; the learning state every pair, as a fit lasts a fraction of a
  // second and /diagnostics would otherwise rarely show "fitting".
  if (pairs_ % 15 == 0) {
    updateDiagnostics();
  } else if (learner_) {
    diagnostics_.setValue("learning", learner_->status().state);
  }
}

void OnlineLearningRos::chargeTracking(double cpu_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (learner_) learner_->chargeTrackingElsewhere(cpu_s);
}

bool OnlineLearningRos::fallingBack() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return fallingBackLocked();
}

bool OnlineLearningRos::fallingBackLocked() const {
  return params_.fallback_to_gyro && learner_ && learner_->fallingBack();
}

void OnlineLearningRos::timeWentBack() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (learner_) learner_->restartTimeline();
  if (calibration_) calibration_->timeWentBack();
  fused_pairs_.clear();  // the old timeline's pairs get no check now (the learner drops its queue)
}

void OnlineLearningRos::setLearning(bool on, double cpu_share) {
  std::lock_guard<std::mutex> lock(mutex_);
  params_.learning = on;
  params_.learning_cpu_share = cpu_share;
  if (!learner_) return;
  learner_->setLearning(on);
  learner_->setCpuShare(cpu_share);
}

bool OnlineLearningRos::waitIdle(double timeout_s) {
  OnlineStabiliserLearner* learner = nullptr;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    learner = learner_.get();
  }
  // Not under the lock: the pairs keep coming while this waits (the learner lives until the next
  // camera, which the caller does not switch to meanwhile).
  return !learner || learner->waitIdle(timeout_s);
}

void OnlineLearningRos::updateDiagnostics() {
  if (!learner_) return;
  const std::shared_ptr<const LearnedStabiliser> model = learner_->model();
  const OnlineLearningStatus s = learner_->status();
  char text[200];
  diagnostics_.setValue("model in use", model->name + " (version " + std::to_string(model->version) + ")");
  std::snprintf(text, sizeof text, "%.3f px (no lens motion %.3f px)", model->held_out_rms_px,
                model->held_out_rms_without_px);
  diagnostics_.setValue("model in use: held-out lens-motion RMS", std::isfinite(model->held_out_rms_px) ? text : "not scored yet");
  diagnostics_.setValue("learning", s.state);
  std::snprintf(text, sizeof text,
                "%.1f s kept, %zu windows (%zu still), %zu fits, %zu swaps (%zu undone, %zu confirmed)",
                s.buffered_s, s.windows_kept, s.windows_still, s.fits, s.swaps, s.swaps_undone, s.swaps_confirmed);
  diagnostics_.setValue("learning data", text);
  diagnostics_.setValue("learning: swap confirmation", s.confirmation);
  std::snprintf(text, sizeof text, "%zu windows and %zu pairs already learned from: not new evidence",
                s.windows_repeated, s.pairs_repeated);
  diagnostics_.setValue("learning: replayed data", text);
  // Said once each: a verdict on a swap, and data coming in that was already learned from.
  const std::size_t verdicts = s.swaps_confirmed + s.swaps_undone_by_pairs + s.swaps_kept_unconfirmed;
  if (verdicts > verdicts_logged_) {
    ROS_INFO_NAMED("compensation", "%s: %s", log_name_.c_str(), s.confirmation.c_str());
    verdicts_logged_ = verdicts;
  }
  if (s.windows_repeated > repeated_logged_) {
    if (repeated_logged_ == 0 || s.windows_kept != kept_at_repeated_log_) {
      ROS_INFO_NAMED("compensation", "%s: the data coming in was already learned from (a recording replayed?): not "
                     "counted as new evidence for a fit or a swap's confirmation (%zu windows, %zu pairs so far)",
                     log_name_.c_str(), s.windows_repeated, s.pairs_repeated);
    }
    repeated_logged_ = s.windows_repeated;
    kept_at_repeated_log_ = s.windows_kept;
  }
  std::snprintf(text, sizeof text, "%.1f %% of the pairs checked (%zu checked, %zu without enough tracks)",
                s.pairs_checked ? 100.0 * s.pairs_falling_back / s.pairs_checked : 0.0, s.pairs_checked,
                s.pairs_unusable);
  diagnostics_.setValue("fallback to the plain gyro", params_.fallback_to_gyro ? text : "off (~fallback_to_gyro)");
  std::snprintf(text, sizeof text,
                "%.1f %% of a core (budget %.0f %%; the fusion's tracking %.1f %%); %zu pairs skipped over budget, "
                "%zu fits waited for it; %zu pairs dropped (queue full)",
                s.wall_s > 0.0 ? 100.0 * s.cpu_s / s.wall_s : 0.0, 100.0 * params_.learning_cpu_share,
                s.wall_s > 0.0 ? 100.0 * s.tracking_elsewhere_cpu_s / s.wall_s : 0.0,
                s.pairs_over_budget, s.fits_delayed_by_budget, s.pairs_dropped_busy);
  diagnostics_.setValue("learning CPU", text);
  if (!s.last_choice.empty()) diagnostics_.setValue("learning: last choice", s.last_choice);
  if (!s.last_problem.empty()) diagnostics_.setValue("learning: last problem", s.last_problem);
}

}  // namespace deep_ois
