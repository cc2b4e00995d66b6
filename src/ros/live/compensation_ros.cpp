#include "deep_ois/ros/live/compensation_ros.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>


#include <boost/make_shared.hpp>
#include <opencv2/core/utility.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "deep_ois/core/common/printf_text.h"
#include "deep_ois/core/flow/flow_color.h"
#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/patch_homography_map.h"
#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/ros/live/callback_guard.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/messages/message_validation.h"

namespace deep_ois {

namespace {
constexpr double kWarnPeriodS = 2.0;
// A handling delay this much below the smallest seen means ROS time went back (seconds; the gyro
// flow nodelet's ~time_jump_reset default).
constexpr double kTimelineJumpS = 1.0;
// The optional outputs shed under overload (OutputShedding indices), costliest first as measured.
// ~fusion: the least prior sigma taken from the per-pair checks, pixels (their residual holds the
// tracks' noise; benchmark_fusion's floor).
constexpr double kMinFusionPriorSigmaPx = 0.1;
constexpr std::size_t kShedColour = 0, kShedAligned = 1, kShedGhost = 2;
// Shedding starts at a quarter of ~max_lag and ends below a tenth: the plain compensated flow keeps
// up well before a pair would be dropped.
OutputShedding makeShedding(double max_lag_s) {
  OutputSheddingOptions options;
  options.shed_above_s = 0.25 * max_lag_s;
  options.restore_below_s = 0.1 * max_lag_s;
  return OutputShedding({"compensated_flow/color", "aligned/image_raw", "aligned/ghost"}, options);
}
double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

CompensationRos::CompensationRos(ros::NodeHandle nh, ros::NodeHandle private_nh)
    : nh_(nh),
      private_nh_(private_nh),
      log_name_(private_nh.getNamespace()),
      params_(loadCompensationParameters(private_nh)),
      compensator_kind_(compensatorKindFor(params_.model_path)),
      it_(nh),
      matcher_(FlowFrameMatcherOptions{static_cast<std::size_t>(params_.image_cache_size),
                                       static_cast<std::size_t>(params_.max_pending_flows), params_.max_wait_s}),
      shedding_(makeShedding(params_.max_lag_s)) {
  if (compensator_kind_ == CompensatorKind::kStabiliserModel) {
    stabiliser_ = std::make_unique<StabiliserFlowCompensator>(StabiliserModelFile::load(params_.model_path));
  } else {
    model_ = std::make_unique<CompensationModel>(CompensationModel::load(params_.model_path));
    stream_ = std::make_unique<CompensationStream>(*model_);
  }
  setTorchThreads(params_.torch_threads);
  // OpenCV's thread count is process-wide: the warp (map build and remaps) is the OpenCV work
  // that splits into stripes; one thread unless ~warp_threads asks for more.
  cv::setNumThreads(params_.warp_threads);
  diagnostics_ = std::make_unique<LiveDiagnostics>(
      nh_, private_nh_, std::vector<std::string>{"gyro flows", "images", "compensated flows"}, "compensated flows",
      nh_.resolveName("image_raw"));
  diagnostics_->setValue("model", params_.model_path);
  if (model_) {
    const ModelMetadata& m = model_->metadata();
    diagnostics_->setValue("model preset", m.preset);
    diagnostics_->setValue("working grid [px]", std::to_string(m.working_grid.width) + "x" +
                                                    std::to_string(m.working_grid.height));
    diagnostics_->setValue("torch threads", std::to_string(params_.torch_threads));
  } else {
    diagnostics_->setValue("model kind", "learned stabiliser model");
  }
  if (params_.fusion && model_) {
    ROS_WARN_NAMED("compensation", "%s: ~fusion applies to a stabiliser model's per-patch motion only: the network's "
                   "flow %s is published unfused", log_name_.c_str(), params_.model_path.c_str());
  }
  // A generic model (trained on several cameras, or before models recorded theirs) cannot be
  // checked against the stream; say so rather than "matches".
  diagnostics_->setValue("model camera", modelCamera().known() ? modelCamera().summary()
                                                               : "none recorded (a generic model)");
  // Live-tunable parameters; built before the lock below (it applies the values once here).
  reconfigure_ = std::make_unique<CompensationReconfigure>(
      private_nh_, "compensation",
      CompensationLiveParameters{params_.color_max_flow_px, params_.warp_iterations, params_.warp_threads,
                                 params_.max_wait_s, params_.learning, params_.learning_cpu_share, params_.fusion},
      [this](const CompensationLiveParameters& live) {
        std::lock_guard<std::mutex> lock(mutex_);
        params_.color_max_flow_px = live.color_max_flow_px;
        params_.warp_iterations = live.warp_iterations;
        if (live.warp_threads != params_.warp_threads) cv::setNumThreads(live.warp_threads);
        params_.warp_threads = live.warp_threads;
        params_.max_wait_s = live.max_wait_s;
        matcher_.setMaxWait(live.max_wait_s);
        diagnostics_->setValue("color_max_flow [px]", std::to_string(live.color_max_flow_px));
        diagnostics_->setValue("warp_iterations", std::to_string(live.warp_iterations));
        diagnostics_->setValue("warp_threads", std::to_string(live.warp_threads));
        params_.learning = live.learning;
        params_.learning_cpu_share = live.learning_cpu_share;
        if (learning_) learning_->setLearning(live.learning, live.learning_cpu_share);
        params_.fusion = live.fusion;
        if (stabiliser_) diagnostics_->setValue("fusion", live.fusion ? "on" : "off");
        // Said from the moment the fusion is on (the reconfigure applies the loaded values at start).
        if (stabiliser_ && live.fusion && fusion_counts_.pairs == 0)
          diagnostics_->setValue("fusion: last prior kept", "none yet");
      });
  // Held across every advertise (compensation_check's too): a subscriber connecting meanwhile
  // waits in connectCallback until the publishers exist.
  std::lock_guard<std::mutex> lock(mutex_);
  if (stabiliser_) {
    learning_ = std::make_unique<OnlineLearningRos>(nh_, params_, stabiliser_->model(), *diagnostics_, log_name_,
                                                    [this] { connectCallback(); });
  }
  auto on_subscribers = [this](const ros::SingleSubscriberPublisher&) { connectCallback(); };
  auto on_image_subscribers = [this](const image_transport::SingleSubscriberPublisher&) { connectCallback(); };
  compensated_pub_ = nh_.advertise<GyroFlow>("compensated_flow", 5, on_subscribers, on_subscribers);
  color_pub_ = it_.advertise("compensated_flow/color", 5, on_image_subscribers, on_image_subscribers);
  aligned_pub_ = it_.advertise("aligned/image_raw", 5, on_image_subscribers, on_image_subscribers);
  ghost_pub_ = it_.advertise("aligned/ghost", 5, on_image_subscribers, on_image_subscribers);
  flow_image_pub_ = FlowImagePublisher(nh_, "compensated_flow/image", [this] { connectCallback(); });
  // Gives up on flows whose frames stopped coming (no image callback runs then).
  expire_timer_ = nh_.createWallTimer(ros::WallDuration(0.25), &CompensationRos::expireTimerCallback, this);
  updateSubscriptions();  // subscribers that connected before the callbacks could see them
  if (model_) {
    const ModelMetadata& m = model_->metadata();
    ROS_INFO_NAMED("compensation", "%s: model %s (preset %s, working grid %dx%d, trained %d epochs for %s), %d torch "
                   "thread(s), %d warp thread(s)", log_name_.c_str(),
                   params_.model_path.c_str(), m.preset.c_str(), m.working_grid.width, m.working_grid.height,
                   m.training.epochs, m.camera.summary().c_str(), params_.torch_threads, params_.warp_threads);
  } else {
    const StabiliserModelFile& m = stabiliser_->model();
    ROS_INFO_NAMED("compensation", "%s: learned stabiliser model %s ('%s', trained for %s on %zu recordings), %d warp "
                   "thread(s)", log_name_.c_str(), params_.model_path.c_str(), m.name.c_str(),
                   m.camera.summary().c_str(), m.training.recordings, params_.warp_threads);
  }
}

CompensationRos::~CompensationRos() {
  expire_timer_.stop();
  reconfigure_.reset();  // no more reconfigure callbacks into this
  learning_.reset();     // its threads end (a fit in progress first) before the diagnostics go
  diagnostics_.reset();
  std::lock_guard<std::mutex> lock(mutex_);
  gyro_flow_sub_.shutdown();
  image_sub_.shutdown();
}

bool CompensationRos::anyOutputWanted() const {
  // The per-pair checks are an output too: a lone `rostopic echo compensation_check` gets them.
  return compensated_pub_.getNumSubscribers() > 0 || color_pub_.getNumSubscribers() > 0 ||
         aligned_pub_.getNumSubscribers() > 0 || ghost_pub_.getNumSubscribers() > 0 || flow_image_pub_.wanted() ||
         (learning_ && learning_->checksWanted());
}

void CompensationRos::connectCallback() {
  std::lock_guard<std::mutex> lock(mutex_);
  updateSubscriptions();
}

void CompensationRos::updateSubscriptions() {
  const bool wanted = anyOutputWanted();
  const bool subscribed = static_cast<bool>(gyro_flow_sub_);
  if (!wanted && subscribed) {
    gyro_flow_sub_.shutdown();
    image_sub_.shutdown();
    matcher_.clear();
  } else if (wanted && !subscribed) {
    const image_transport::TransportHints hints("raw", ros::TransportHints(), private_nh_);
    image_sub_ = it_.subscribe("image_raw", params_.image_queue_size, &CompensationRos::imageCallback, this, hints);
    gyro_flow_sub_ = nh_.subscribe("gyro_flow", params_.gyro_flow_queue_size, &CompensationRos::gyroFlowCallback, this);
  }
}

template <typename Handle>
void CompensationRos::guarded(const std::string& topic, Handle handle) {
  // A flow whose processing threw has no output: counted with the others.
  if (!runGuarded("compensation", log_name_, topic, errors_, handle)) countDrop("an error while processing (warned)");
}

void CompensationRos::imageCallback(const sensor_msgs::ImageConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  diagnostics_->tick("images");
  guarded(image_sub_.getTopic(), [&] {
    checkStampClock(msg->header.stamp, image_sub_.getTopic());
    const std::string problem = validateImage(*msg);
    if (!problem.empty()) {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: refusing frame %.6f on %s: %s", log_name_.c_str(),
                              msg->header.stamp.toSec(), image_sub_.getTopic().c_str(), problem.c_str());
      return;
    }
    if (static_cast<double>(msg->width) * msg->height > params_.max_image_pixels) {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation",
                              "%s: refusing frame %.6f on %s: %ux%u is more than ~max_image_pixels "
                              "(%d) pixels", log_name_.c_str(),
                              msg->header.stamp.toSec(), image_sub_.getTopic().c_str(), msg->width, msg->height,
                              params_.max_image_pixels);
      return;
    }
    settle(matcher_.addFrame(static_cast<std::int64_t>(msg->header.stamp.toNSec()), msg,
                             ros::WallTime::now().toSec()));
  });
  reportDrops();
}

void CompensationRos::gyroFlowCallback(const GyroFlowConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  diagnostics_->tick("gyro flows");
  guarded(gyro_flow_sub_.getTopic(), [&] {
    checkStampClock(msg->header.stamp, gyro_flow_sub_.getTopic());
    // Every field, before anything uses one: what is published is made from a valid input (the
    // methods that pass input fields through, as measured or the fallback to the plain gyro, too).
    const std::string problem = gyroFlowProblem(*msg);
    if (!problem.empty()) {
      countDrop("malformed gyro flow (warned)");
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: refusing gyro flow %.6f on %s: %s", log_name_.c_str(),
                              msg->header.stamp.toSec(), gyro_flow_sub_.getTopic().c_str(), problem.c_str());
      return;
    }
    if (last_flow_stamp_ && msg->previous_stamp > *last_flow_stamp_) {
      // Consecutive pairs chain; a gap means flows lost upstream (the gyro flow nodelet says why)
      // or in a full subscriber queue.
      countDrop("gyro flows missing between two received ones");
    }
    if (last_flow_stamp_ && msg->header.stamp < *last_flow_stamp_) min_delay_s_.reset();  // time went back
    last_flow_stamp_ = msg->header.stamp;
    settle(matcher_.addFlow(static_cast<std::int64_t>(msg->previous_stamp.toNSec()),
                            static_cast<std::int64_t>(msg->header.stamp.toNSec()), msg, ros::WallTime::now().toSec()));
  });
  reportDrops();
}

void CompensationRos::expireTimerCallback(const ros::WallTimerEvent&) {
  std::lock_guard<std::mutex> lock(mutex_);
  guarded(gyro_flow_sub_.getTopic(), [&] { settle(matcher_.expire(ros::WallTime::now().toSec())); });
  reportDrops();
}

void CompensationRos::countDrop(const std::string& reason) {
  drops_.add(reason);
  diagnostics_->drop(reason);
}

void CompensationRos::settle(const std::vector<Matcher::Settled>& settled) {
  for (const Matcher::Settled& s : settled) {
    if (!s.matched) {
      countDrop(flowDropReasonText(s.reason));
      guarded(gyro_flow_sub_.getTopic(), [&] { observeOnly(*s.flow); });
      continue;
    }
    const double lag_s = lagS(s.flow->header.stamp);
    // Late: the optional outputs go first (one more per late pair), the pair only beyond ~max_lag.
    const std::size_t shed_before = shedding_.level();
    if (shedding_.beforePair(lag_s) != shed_before) sayShedding(lag_s, shed_before);
    if (lag_s > params_.max_lag_s) {
      countDrop("compensation more than ~max_lag behind its input");
      guarded(gyro_flow_sub_.getTopic(), [&] { observeOnly(*s.flow); });
      continue;
    }
    guarded(gyro_flow_sub_.getTopic(), [&] { process(*s.flow, s.frame_a, s.frame_b); });
  }
}

void CompensationRos::sayShedding(double lag_s, std::size_t shed_before) {
  diagnostics_->setValue("overload: shedding now", shedding_.describeShed());
  diagnostics_->setValue("overload: pairs with an output shed", shedding_.describeCounts());
  if (shedding_.level() > shed_before) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation",
                            "%s: compensation %.3f s behind its input on %s: shedding %s (the costliest optional "
                            "outputs first: %s) until it keeps up; the compensated flow goes on, and a pair is "
                            "dropped only beyond ~max_lag (%.3f s)",
                            log_name_.c_str(), lag_s, gyro_flow_sub_.getTopic().c_str(),
                            shedding_.describeShed().c_str(), shedding_.describeOrder().c_str(), params_.max_lag_s);
  }
}

void CompensationRos::observeOnly(const GyroFlow& gyro) {
  if (stabiliser_) {
    sayTimeJump(gyro, stabiliser_->observe(gyro));
    return;
  }
  std::vector<Eigen::Matrix3d> homographies;
  cv::Mat gyro_flow;
  if (!readGyroFlowMsg(gyro, homographies, gyro_flow).empty() || !cv::checkRange(gyro_flow)) return;
  if (!last_flow_grid_ || *last_flow_grid_ != gyro_flow.size()) return;  // process() restarts it
  stream_->observe(gyro_flow, static_cast<std::int64_t>(gyro.previous_stamp.toNSec()),
                  static_cast<std::int64_t>(gyro.header.stamp.toNSec()));
}

const CameraDescription& CompensationRos::modelCamera() const {
  return stabiliser_ ? stabiliser_->model().camera : model_->metadata().camera;
}

bool CompensationRos::checkModelCamera(const GyroFlow& gyro) {
  CameraDescription stream;
  stream.width = static_cast<int>(gyro.image_width);
  stream.height = static_cast<int>(gyro.image_height);
  stream.fx = gyro.K[0];
  stream.fy = gyro.K[4];
  stream.cx = gyro.K[2];
  stream.cy = gyro.K[5];
  stream.readout_time_s = gyro.readout_time;
  // No frame rate: one pair's interval is jittery and doubles when a frame is lost.
  const std::string summary = stream.summary();
  if (summary == checked_camera_) return camera_check_.empty() || !params_.require_matching_camera;
  checked_camera_ = summary;
  const CameraDescription& trained = modelCamera();
  camera_check_ = trained.differencesTo(stream);
  diagnostics_->setValue("model camera check", !trained.known()      ? "not checked (the model records no camera)"
                                               : camera_check_.empty() ? "matches"
                                                                       : camera_check_);
  if (camera_check_.empty()) return true;
  // A stabiliser model works in focal-length units and degrades gracefully on another camera; the
  // network sees working-grid pixels of its training camera's flows.
  const char* kind = stabiliser_ ? "stabiliser model" : "network model";
  const char* train_tool = stabiliser_ ? "train_stabiliser" : "fundamental_mixtures and train";
  const char* anyway = stabiliser_ ? "its units follow the focal length" : "expect a weaker compensation";
  if (params_.require_matching_camera) {
    ROS_ERROR_NAMED("compensation", "%s: the %s %s was trained for %s but the gyro flows are of %s (%s): refusing "
                    "them (~require_matching_camera is true; train a model for this camera with %s)",
                    log_name_.c_str(), kind, params_.model_path.c_str(), trained.summary().c_str(), summary.c_str(),
                    camera_check_.c_str(), train_tool);
  } else {
    ROS_WARN_NAMED("compensation", "%s: the %s %s was trained for %s but the gyro flows are of %s (%s): compensating "
                   "anyway (%s); set ~require_matching_camera to refuse, or train a model for this camera with %s",
                   log_name_.c_str(), kind, params_.model_path.c_str(), trained.summary().c_str(), summary.c_str(),
                   camera_check_.c_str(), anyway, train_tool);
  }
  return !params_.require_matching_camera;
}

void CompensationRos::sayTimeJump(const GyroFlow& gyro, double back_s) {
  if (!(back_s > 0.0)) return;
  if (learning_) learning_->timeWentBack();
  diagnostics_->setValue("stabiliser restarts after time went back", std::to_string(stabiliser_->timeJumps()));
  // Once per jump (only the first pair of the new timeline reports one): not throttled.
  ROS_WARN_NAMED("compensation",
                 "%s: gyro flow stamps on %s went back by %.3f s (to %.6f; a bag that loops or a restarted "
                 "replay): the stabiliser model restarts from a centred lens, warmed up on the gyro history "
                 "the flows carry (up to %.1f s)",
                 log_name_.c_str(), gyro_flow_sub_.getTopic().c_str(), back_s, gyro.previous_stamp.toSec(),
                 kStabiliserWarmUpS);
}

void CompensationRos::sayCalibrationChange(const GyroFlow& gyro) {
  const int changes = stabiliser_->calibrationChanges();
  if (changes == calibration_changes_said_) return;
  calibration_changes_said_ = changes;
  const int restarts = stabiliser_->calibrationRestarts();
  diagnostics_->setValue("stabiliser: calibration changes carried across",
                         std::to_string(changes - restarts) + " (" + std::to_string(restarts) +
                             " restarted: moved back beyond the model's history)");
  // Once per applied calibration (a few a minute at most): not throttled.
  ROS_INFO_NAMED("compensation",
                 "%s: gyro flows on %s now use calibration epoch %u (time offset %.3f ms): the stabiliser model %s",
                 log_name_.c_str(), gyro_flow_sub_.getTopic().c_str(), gyro.calibration_epoch, 1e3 * gyro.time_offset,
                 restarts > calibration_restarts_said_ ? "restarts (the offset moved back beyond its history)"
                                                       : "carries its state across the change");
  calibration_restarts_said_ = restarts;
}

void CompensationRos::checkStampClock(const ros::Time& stamp, const std::string& topic) {
  const bool say = stamp_clock_.observe(stamp.toSec(), ros::Time::now().toSec());
  diagnostics_->setClockProblem(stamp_clock_.describe());
  // Once per timeline (the check starts over when time goes back): not throttled.
  if (say) {
    ROS_WARN_NAMED("compensation", "%s: %s: %s", log_name_.c_str(), topic.c_str(), stamp_clock_.describe().c_str());
  }
}

double CompensationRos::lagS(const ros::Time& stamp_b) {
  const ros::Time now = ros::Time::now();
  if (now.isZero()) return 0.0;  // simulated time before the first /clock message
  const double delay_s = (now - stamp_b).toSec();
  // A delay far below the smallest seen is not a faster pipeline but a pair of the timeline before
  // ROS time went back (a bag loop: a pair still pending when the clock restarted). It is not late,
  // and it must not become the reference, or every pair of the new timeline would look late.
  if (min_delay_s_ && delay_s < *min_delay_s_ - kTimelineJumpS) return 0.0;
  if (!min_delay_s_ || delay_s < *min_delay_s_) min_delay_s_ = delay_s;
  return delay_s - *min_delay_s_;
}

void CompensationRos::reportDrops() {
  const ros::WallTime now = ros::WallTime::now();
  if (!drops_.pending() || (now - last_drop_report_).toSec() < kWarnPeriodS) return;
  last_drop_report_ = now;
  const std::size_t count = drops_.pendingCount();
  ROS_WARN_NAMED("compensation",
                 "%s: %zu gyro flow(s) on %s without output since the last report (%zu since start; "
                 "frames on %s): %s", log_name_.c_str(),
                 count, gyro_flow_sub_.getTopic().c_str(), drops_.total(), image_sub_.getTopic().c_str(),
                 drops_.take().c_str());
}

std::optional<CompensationRos::CompensatedMotion> CompensationRos::asMeasured(const GyroFlow& gyro,
                                                                              const cv::Mat& gyro_flow) {
  // The network's motion history holds gyro flows: it restarts at the next pair without the log
  // (as at the start of a stream) rather than mixing in lens-corrected ones; a stabiliser model
  // keeps following the gyro stream.
  if (stream_) stream_->reset();
  if (stabiliser_) {
    sayTimeJump(gyro, stabiliser_->observe(gyro));
    sayCalibrationChange(gyro);
  }
  return CompensatedMotion{gyro_flow.clone(), {}, {}};
}

std::optional<CompensationRos::CompensatedMotion> CompensationRos::withStabiliserModel(
    const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a, const sensor_msgs::ImageConstPtr& image_b,
    const std::vector<Eigen::Matrix3d>& gyro_homographies, const cv::Mat& gyro_flow) {
  if (learning_) learning_->beforePair(gyro, *stabiliser_);  // the model in use (a swap is said once)
  std::vector<FeatureMatch> tracks;
  const std::optional<PairFusion> fusion = params_.fusion ? fusionFor(image_a, image_b, tracks) : std::nullopt;
  const auto compensate_start = std::chrono::steady_clock::now();
  StabiliserFlowResult result = stabiliser_->compensate(gyro, fusion ? &*fusion : nullptr);
  if (fusion && result.ok) countFusion(result, secondsSince(compensate_start));
  sayTimeJump(gyro, result.time_jump_back_s);
  sayCalibrationChange(gyro);
  if (!result.ok) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: no compensation for gyro flow %.6f: %s",
                            log_name_.c_str(), gyro.header.stamp.toSec(), result.reason.c_str());
    countDrop("stabiliser model: " + result.reason);
    return std::nullopt;
  }
  if (learning_) learning_->afterPair(gyro, image_a, image_b, result, gyro_homographies, fusion ? &tracks : nullptr);
  // The checks found the model worse than the plain gyro: the gyro's motion is published.
  if (publishesPlainGyro(CompensationMethod::kStabiliserModel, learning_ && learning_->fallingBack())) {
    return CompensatedMotion{gyro_flow.clone(), gyro_homographies, result.camera};
  }
  return CompensatedMotion{result.flow, std::move(result.homographies), result.camera};
}

std::optional<PairFusion> CompensationRos::fusionFor(const sensor_msgs::ImageConstPtr& image_a,
                                                     const sensor_msgs::ImageConstPtr& image_b,
                                                     std::vector<FeatureMatch>& tracks) {
  const auto start = std::chrono::steady_clock::now();
  try {
    tracks = fusion_tracker_.matchAtWidth(cv_bridge::toCvShare(image_a)->image, cv_bridge::toCvShare(image_b)->image,
                                          params_.learning_tracking_width_px);
  } catch (const std::exception& e) {  // an encoding the tracker cannot read (cv_bridge, toGray8)
    diagnostics_->setValue("fusion: pairs not tracked (model's motion published)",
                           std::to_string(++fusion_counts_.untracked));
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: ~fusion: cannot track the %s frames on %s (%s): the "
                            "model's motion is published", log_name_.c_str(), image_b->encoding.c_str(),
                            image_sub_.getTopic().c_str(), e.what());
    return std::nullopt;
  }
  fusion_counts_.tracking_s += secondsSince(start);
  PairFusion fusion;
  fusion.options = &fusion_options_;
  fusion.tracks = &tracks;
  // The prior's sigma: the median model residual of the recent per-pair checks (never below 0.1
  // px: it holds the tracks' noise), as benchmark_fusion takes it; the default before the first.
  const std::optional<double> recent = learning_ ? learning_->recentModelResidualPx() : std::nullopt;
  if (recent) fusion.prior_sigma_px = std::max(kMinFusionPriorSigmaPx, *recent);
  return fusion;
}

void CompensationRos::countFusion(const StabiliserFlowResult& result, double compensate_s) {
  FusionCounts& c = fusion_counts_;
  ++c.pairs;
  c.compensate_s += compensate_s;
  if (result.fusion_failed) {
    ++c.failed;
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: ~fusion: %s", log_name_.c_str(),
                            result.fused->reason.c_str());
  }
  if (result.fused && result.fused->refined) {
    ++c.refined;
    c.correction_sum_px += result.fused->mean_correction_px;
  } else if (result.fused) {
    diagnostics_->setValue("fusion: last prior kept", result.fused->reason);
  }
  const auto fixed = [](double value, int digits) { return printfText("%.*f", digits, value); };
  diagnostics_->setValue("fusion: pairs refined [%]", fixed(100.0 * c.refined / c.pairs, 1) + " (" +
                                                          std::to_string(c.refined) + " of " +
                                                          std::to_string(c.pairs) + ")");
  diagnostics_->setValue("fusion: mean correction [px]", c.refined ? fixed(c.correction_sum_px / c.refined, 3) : "-");
  diagnostics_->setValue("fusion: failures (model's motion published)", std::to_string(c.failed));
  diagnostics_->setValue("fusion: tracking a pair [ms]", fixed(1e3 * c.tracking_s / c.pairs, 2));
  diagnostics_->setValue("fusion: model and fusion a pair [ms]", fixed(1e3 * c.compensate_s / c.pairs, 2));
}

std::optional<CompensationRos::CompensatedMotion> CompensationRos::withNetwork(const GyroFlow& gyro,
                                                                               const cv::Mat& gyro_flow) {
  return CompensatedMotion{stream_->compensate(gyro_flow, static_cast<std::int64_t>(gyro.previous_stamp.toNSec()),
                                               static_cast<std::int64_t>(gyro.header.stamp.toNSec())),
                           {}, {}};
}

void CompensationRos::process(const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a,
                              const sensor_msgs::ImageConstPtr& image_b) {
  std::vector<Eigen::Matrix3d> homographies;
  cv::Mat gyro_flow;
  const std::string problem = readGyroFlowMsg(gyro, homographies, gyro_flow);
  if (!problem.empty()) {
    countDrop("bad gyro flow message");
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: dropping gyro flow %.6f on %s: %s", log_name_.c_str(),
                            gyro.header.stamp.toSec(), gyro_flow_sub_.getTopic().c_str(), problem.c_str());
    diagnostics_->drop("invalid gyro flow");
    return;
  }
  if (!cv::checkRange(gyro_flow)) {
    countDrop("gyro flow holds NaN or inf");
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: dropping gyro flow %.6f on %s: its flow holds NaN or inf", log_name_.c_str(),
                            gyro.header.stamp.toSec(), gyro_flow_sub_.getTopic().c_str());
    return;
  }
  if (!last_flow_grid_ || *last_flow_grid_ != gyro_flow.size()) {
    // The motion history sums flows of one grid: a new grid (a reconfigured gyro flow) restarts it.
    if (last_flow_grid_ && stream_) stream_->reset();
    last_flow_grid_ = gyro_flow.size();
  }
  if (params_.test_processing_delay_s > 0.0) ros::WallDuration(params_.test_processing_delay_s).sleep();
  if (image_a->width != gyro.image_width || image_a->height != gyro.image_height ||
      image_b->width != gyro.image_width || image_b->height != gyro.image_height) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation",
                            "%s: dropping gyro flow %.6f: it is for %ux%u images but %s has %ux%u", log_name_.c_str(),
                            gyro.header.stamp.toSec(), gyro.image_width, gyro.image_height,
                            image_sub_.getTopic().c_str(), image_b->width, image_b->height);
    countDrop("gyro flow and frames of different sizes");
    return;
  }
  const CompensationMethod method =
      compensationMethodFor(compensator_kind_, gyro.motion_model == GyroFlow::MOTION_GYRO_LENS_LOG);
  if (methodUsesModel(method) && !checkModelCamera(gyro)) {
    countDrop("model trained for another camera (~require_matching_camera)");
    return;
  }
  std::optional<CompensatedMotion> motion;
  switch (method) {
    case CompensationMethod::kAsMeasured:
      motion = asMeasured(gyro, gyro_flow);
      break;
    case CompensationMethod::kStabiliserModel:
      motion = withStabiliserModel(gyro, image_a, image_b, homographies, gyro_flow);
      break;
    case CompensationMethod::kNetwork:
      motion = withNetwork(gyro, gyro_flow);
      break;
  }
  if (!motion) return;  // counted and said where it failed
  const cv::Mat& compensated = motion->flow;
  const std::vector<Eigen::Matrix3d>& compensated_homographies = motion->homographies;
  const CameraModel& compensated_camera = motion->camera;
  bool finite_homographies = true;
  for (const Eigen::Matrix3d& h : compensated_homographies) finite_homographies = finite_homographies && h.allFinite();
  if (!cv::checkRange(compensated) || !finite_homographies) {
    // Never publish NaN: a model that diverges on this input gives no output for it.
    if (stream_) stream_->reset();
    countDrop("the model output holds NaN or inf");
    return;
  }
  GyroFlowPtr compensated_msg;
  if (compensated_pub_.getNumSubscribers() > 0) {
    compensated_msg = boost::make_shared<GyroFlow>(gyro);
    // Same grid, encoding and size as the gyro flow (readGyroFlowMsg checked the layout).
    CV_Assert(compensated.isContinuous() &&
              compensated_msg->flow.data.size() == compensated.total() * compensated.elemSize());
    std::memcpy(compensated_msg->flow.data.data(), compensated.data, compensated_msg->flow.data.size());
    // A stabiliser model's motion is per patch too: the message carries it (the network's stays
    // the gyro input's, its output being only the flow).
    if (!compensated_homographies.empty()) compensated_msg->homographies = flattenMatrices(compensated_homographies);
    // The whole message, fields passed through included, before anything of this pair goes out.
    const std::string problem = gyroFlowProblem(*compensated_msg);
    if (!problem.empty()) {
      countDrop("an output that failed validation (warned)");
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: not publishing the compensation of gyro flow %.6f "
                              "on %s (%s): %s", log_name_.c_str(), gyro.header.stamp.toSec(),
                              gyro_flow_sub_.getTopic().c_str(), toString(method), problem.c_str());
      return;
    }
  }
  diagnostics_->tick("compensated flows");
  diagnostics_->latency((ros::Time::now() - gyro.header.stamp).toSec());

  if (compensated_msg) compensated_pub_.publish(compensated_msg);
  const cv::Size camera_size(static_cast<int>(gyro.image_width), static_cast<int>(gyro.image_height));
  flow_image_pub_.publish(gyro.header, compensated);
  // The optional outputs, each unless shed under overload (OutputShedding), each timed for the
  // shedding order (wall time: what the pipeline's lag is made of).
  const bool subscribed_color = color_pub_.getNumSubscribers() > 0;
  const bool subscribed_aligned = aligned_pub_.getNumSubscribers() > 0;
  const bool subscribed_ghost = ghost_pub_.getNumSubscribers() > 0;
  const bool want_color = subscribed_color && !shedding_.shed(kShedColour, subscribed_color);
  const bool want_aligned = subscribed_aligned && !shedding_.shed(kShedAligned, subscribed_aligned);
  const bool want_ghost = subscribed_ghost && !shedding_.shed(kShedGhost, subscribed_ghost);
  if (want_color) {
    const auto start = std::chrono::steady_clock::now();
    cv::Mat color;
    sensor_msgs::ImagePtr msg = makeImageMsg(gyro.header, sensor_msgs::image_encodings::RGB8, compensated.size(), color);
    colorizeFlow(compensated, params_.color_max_flow_px, color);
    color_pub_.publish(msg);
    shedding_.measured(kShedColour, secondsSince(start));
  }
  // The map serves both: its cost goes to the aligned frame when it is made, else to the ghost.
  const auto map_start = std::chrono::steady_clock::now();
  double map_s = 0.0;
  if (want_aligned || want_ghost) {
    // The flow inverted on its grid; per camera pixel only the map's interpolation and the remaps.
    if (!compensated_homographies.empty()) {
      // Per-patch homographies (a stabiliser model): the map straight from them, no flow inversion.
      if (!patch_map_builder_ || !(patch_map_builder_->camera() == compensated_camera) ||
          patch_map_builder_->patchCount() != static_cast<int>(compensated_homographies.size())) {
        patch_map_builder_ = std::make_unique<PatchHomographyMapBuilder>(
            compensated_camera, static_cast<int>(compensated_homographies.size()));
      }
      patch_map_builder_->build(compensated_homographies, warp_map_);
    } else {
      buildFixedPointBackwardMap(compensated, camera_size, params_.warp_iterations, warp_map_);
    }
    map_s = secondsSince(map_start);
  }
  const std_msgs::Header& header = image_b->header;
  cv::Mat aligned;
  if (want_aligned) {
    const auto start = std::chrono::steady_clock::now();
    // Any encoding: the warp works per channel on the frame's own pixels.
    const cv_bridge::CvImageConstPtr a = cv_bridge::toCvShare(image_a);
    sensor_msgs::ImagePtr msg = makeImageMsg(header, image_a->encoding, camera_size, aligned);
    warpWithFixedPointMap(a->image, warp_map_, aligned);
    aligned_pub_.publish(msg);
    shedding_.measured(kShedAligned, map_s + secondsSince(start));
  }
  // The pair has its output now: a ghost that cannot be drawn is said and counted on its own,
  // not as a flow without output.
  if (want_ghost) {
    const auto start = std::chrono::steady_clock::now();
    try {
      cv::Mat ghost;
      sensor_msgs::ImagePtr msg = makeImageMsg(header, sensor_msgs::image_encodings::RGB8, camera_size, ghost);
      // Both frames with frame b's display range (depth or thermal frames).
      DisplayRange range;
      const cv_bridge::CvImageConstPtr b = toRgb8ForDisplay(image_b, range);
      if (want_aligned && image_a->encoding == sensor_msgs::image_encodings::RGB8) {
        ghostOverlay(aligned, b->image, ghost);  // frame a is already warped in RGB
      } else {
        warpWithFixedPointMap(toRgb8ForDisplay(image_a, range)->image, warp_map_, ghost);
        ghostOverlay(ghost, b->image, ghost);
      }
      ghost_pub_.publish(msg);
      shedding_.measured(kShedGhost, (want_aligned ? 0.0 : map_s) + secondsSince(start));
    } catch (const std::exception& e) {  // cv_bridge::Exception, or cv::Exception from OpenCV
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "compensation", "%s: no ghost overlay for the %s frames on %s: %s",
                              log_name_.c_str(), image_b->encoding.c_str(), image_sub_.getTopic().c_str(), e.what());
      diagnostics_->setValue("ghost overlays not drawn", std::to_string(++ghosts_not_drawn_));
    }
  }
  ++published_;
  // The measured order every 15 pairs (a second at 30 fps): it moves slowly.
  if (published_ % 15 == 1) diagnostics_->setValue("overload: shed order (mean cost a pair)", shedding_.describeOrder());
}

}  // namespace deep_ois
