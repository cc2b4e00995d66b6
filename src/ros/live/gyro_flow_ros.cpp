#include "deep_ois/ros/live/gyro_flow_ros.h"

#include <cv_bridge/cv_bridge.h>
#include <image_transport/camera_common.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2/exceptions.h>

#include <Eigen/Geometry>
#include <boost/make_shared.hpp>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/flow/flow_color.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
#include "deep_ois/ros/live/callback_guard.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/messages/message_validation.h"

namespace deep_ois {

namespace {
constexpr double kWarnPeriodS = 2.0;         // throttle of per-message warnings
constexpr double kWaitingCheckPeriodS = 5.0;  // period of the "still waiting" diagnostics
constexpr std::size_t kMaxPendingFrames = 60;  // two seconds of 30 fps video

// The calibration in use, shown with the diagnostics.
void showCalibration(LiveDiagnostics& diagnostics, const GyroFlowParameters& params) {
  const RollingShutterConfig& rs = params.rolling_shutter;
  diagnostics.setValue("time_offset [s]", std::to_string(rs.time_offset_s));
  diagnostics.setValue("readout_time [s]", std::to_string(rs.readout_time_s));
  diagnostics.setValue("patch_count", std::to_string(rs.patch_count));
  diagnostics.setValue("patch_time", rs.patch_time == PatchTimeReference::kPatchStart ? "start" : "centre");
  diagnostics.setValue("R_cam_imu source", params.rotation_from_tf ? "tf" : "~imu_to_camera_rotation");
  diagnostics.setValue("grid [px]", std::to_string(params.grid_size.width) + "x" +
                                        std::to_string(params.grid_size.height));
}

// Whether the calibration a flow is made with differs: timing, mount (or its source) or gyro bias.
bool calibrationDiffers(const GyroFlowParameters& a, const GyroFlowParameters& b) {
  const RollingShutterConfig &x = a.rolling_shutter, &y = b.rolling_shutter;
  return x.time_offset_s != y.time_offset_s || a.time_offset_rate != b.time_offset_rate ||
         a.time_offset_reference_s != b.time_offset_reference_s || x.readout_time_s != y.readout_time_s ||
         x.patch_count != y.patch_count || x.patch_time != y.patch_time ||
         a.rotation_from_tf != b.rotation_from_tf ||
         (!a.rotation_from_tf && x.imu_to_camera_rotation != y.imu_to_camera_rotation) ||
         a.integration.gyro_bias_rad_s != b.integration.gyro_bias_rad_s;
}
}  // namespace

GyroFlowRos::GyroFlowRos(ros::NodeHandle nh, ros::NodeHandle private_nh)
    : nh_(nh),
      private_nh_(private_nh),
      log_name_(private_nh.getNamespace()),
      params_(loadGyroFlowParameters(private_nh)),
      it_(nh),
      imu_buffer_(params_.imu_buffer_duration_s),
      lens_log_(params_.lens_shift_max_gap_s, params_.lens_shift_convention) {
  if (params_.rotation_from_tf) {
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_, nh_);
  }
  // Live-tunable parameters: a change replaces params_ for the next frame pair; the IMU buffer
  // and the frame history stay. Built before the lock below: it applies the values once here.
  diagnostics_ = std::make_unique<LiveDiagnostics>(nh_, private_nh_,
                                                   std::vector<std::string>{"imu", "frames", "gyro flows"},
                                                   "gyro flows", nh_.resolveName("image_raw"));
  reconfigure_ = std::make_unique<GyroFlowReconfigure>(
      private_nh_, "gyro_flow", params_, [this](const GyroFlowParameters& updated) {
        std::lock_guard<std::mutex> lock(mutex_);
        // The flows after a calibration change carry a new epoch (GyroFlow.calibration_epoch): a
        // downstream model then moves its times with the offset instead of taking the change for a
        // jump in time.
        if (calibrationDiffers(params_, updated)) {
          ++calibration_epoch_;
          diagnostics_->setValue("calibration epoch", std::to_string(calibration_epoch_));
        }
        params_ = updated;
        // Back to tf (an empty imu_to_camera_rotation) when the start had the parameter.
        if (params_.rotation_from_tf && !tf_listener_)
          tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_, nh_);
        showCalibration(*diagnostics_, params_);
      });
  // Held across advertise so that a subscriber connecting meanwhile waits for the publishers.
  std::lock_guard<std::mutex> lock(mutex_);
  auto on_flow_subscribers = [this](const ros::SingleSubscriberPublisher&) { connectCallback(); };
  auto on_color_subscribers = [this](const image_transport::SingleSubscriberPublisher&) {
    connectCallback();
  };
  flow_pub_ = nh_.advertise<GyroFlow>("gyro_flow", 5, on_flow_subscribers, on_flow_subscribers);
  color_pub_ = it_.advertise("gyro_flow/color", 5, on_color_subscribers, on_color_subscribers);
  flow_image_pub_ = FlowImagePublisher(nh_, "gyro_flow/image", [this] { connectCallback(); });
  if (params_.follow_online_calibration) {
    // Not an output: it does not make the inputs subscribed. Latched on the compensation's side.
    calibration_sub_ = nh_.subscribe("online_calibration", 5, &GyroFlowRos::onlineCalibrationCallback, this);
  }
  waiting_timer_ = nh_.createWallTimer(ros::WallDuration(kWaitingCheckPeriodS),
                                       &GyroFlowRos::waitingTimerCallback, this);
  ROS_INFO_NAMED("gyro_flow",
                 "%s: %d patches, readout %.4f s, time offset %.4f s, grid %dx%d, IMU-to-camera "
                 "rotation from %s", log_name_.c_str(),
                 params_.rolling_shutter.patch_count, params_.rolling_shutter.readout_time_s,
                 params_.rolling_shutter.time_offset_s, params_.grid_size.width,
                 params_.grid_size.height, params_.rotation_from_tf ? "tf" : "~imu_to_camera_rotation");
}

GyroFlowRos::~GyroFlowRos() {
  reconfigure_.reset();  // no more reconfigure callbacks into this
  diagnostics_.reset();
  waiting_timer_.stop();
  std::lock_guard<std::mutex> lock(mutex_);
  imu_sub_.shutdown();
  camera_sub_.shutdown();
  info_sub_.shutdown();
  lens_sub_.shutdown();
  calibration_sub_.shutdown();
}

void GyroFlowRos::onlineCalibrationCallback(const OnlineCalibrationConstPtr& msg) {
  // Never throws: a message that cannot be applied is said and ignored.
  try {
    // Each version once (a message comes per fit), so that a later dynparam set by hand holds until
    // the next version; a restarted compensation (its versions from 0 again) differs in values.
    if (calibration_applied_ && calibration_applied_->version == msg->version &&
        calibration_applied_->time_offset == msg->time_offset &&
        calibration_applied_->time_offset_rate == msg->time_offset_rate &&
        calibration_applied_->time_offset_reference == msg->time_offset_reference &&
        calibration_applied_->readout_time == msg->readout_time && calibration_applied_->gyro_bias == msg->gyro_bias &&
        calibration_applied_->imu_to_camera_rotation == msg->imu_to_camera_rotation)
      return;
    GyroFlowParameters wanted;
    std::string camera_frame;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      wanted = params_;
      camera_frame = !params_.camera_frame_id.empty() ? params_.camera_frame_id
                                                      : (previous_ ? previous_->frame_id : std::string());
    }
    if (!msg->header.frame_id.empty() && !camera_frame.empty() && msg->header.frame_id != camera_frame) {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: ignoring the online calibration on %s: it is for "
                              "camera frame '%s', this nodelet's is '%s'", log_name_.c_str(),
                              calibration_sub_.getTopic().c_str(), msg->header.frame_id.c_str(), camera_frame.c_str());
      return;
    }
    applyOnlineCalibration(*msg, wanted);
    const std::string problem = reconfigure_->set(wanted);
    if (!problem.empty()) {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: the online calibration version %u on %s is not applied: "
                              "%s", log_name_.c_str(), msg->version, calibration_sub_.getTopic().c_str(),
                              problem.c_str());
      return;
    }
    calibration_applied_ = msg;
    ROS_INFO_NAMED("gyro_flow", "%s: following the online calibration (version %u, %s): time offset %.3f ms "
                   "(drifting %.2f us/s), readout %.3f ms, gyro bias (%.5f, %.5f, %.5f) rad/s%s", log_name_.c_str(),
                   msg->version,
                   msg->confirmation.c_str(), 1e3 * msg->time_offset, 1e6 * msg->time_offset_rate,
                   1e3 * msg->readout_time, msg->gyro_bias[0],
                   msg->gyro_bias[1], msg->gyro_bias[2], msg->mount_estimated ? ", mount estimated" : "");
  } catch (const std::exception& e) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: the online calibration on %s could not be applied: %s",
                            log_name_.c_str(), calibration_sub_.getTopic().c_str(), e.what());
  }
}

void GyroFlowRos::connectCallback() {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool wanted =
      flow_pub_.getNumSubscribers() > 0 || color_pub_.getNumSubscribers() > 0 || flow_image_pub_.wanted();
  const bool subscribed = static_cast<bool>(imu_sub_);
  if (!wanted && subscribed) {
    imu_sub_.shutdown();
    camera_sub_.shutdown();
    info_sub_.shutdown();
    lens_sub_.shutdown();
    resetState("");  // a later subscriber starts from fresh data
  } else if (wanted && !subscribed) {
    const image_transport::TransportHints hints("raw", ros::TransportHints(), private_nh_);
    if (params_.use_camera_info_only) {
      // Stamps, size and intrinsics are all the gyro flow needs: no image is transported. The
      // topic is the image topic's camera_info sibling, as with the image subscription.
      info_sub_ = nh_.subscribe(image_transport::getCameraInfoTopic(nh_.resolveName("image_raw")),
                                params_.image_queue_size, &GyroFlowRos::cameraInfoCallback, this);
      image_topic_ = info_topic_ = info_sub_.getTopic();
    } else {
      camera_sub_ = it_.subscribeCamera("image_raw", params_.image_queue_size,
                                        &GyroFlowRos::cameraCallback, this, hints);
      image_topic_ = camera_sub_.getTopic();
      info_topic_ = camera_sub_.getInfoTopic();
    }
    imu_sub_ = nh_.subscribe("imu", params_.imu_queue_size, &GyroFlowRos::imuCallback, this,
                             ros::TransportHints().tcpNoDelay());
    if (params_.use_lens_shift_log) {
      lens_sub_ = nh_.subscribe("lens_shift", params_.lens_shift_queue_size, &GyroFlowRos::lensShiftCallback,
                                this, ros::TransportHints().tcpNoDelay());
    }
  }
}

void GyroFlowRos::checkRosTimeJump() {
  const ros::Time now = ros::Time::now();
  if (!last_ros_time_.isZero() && now < last_ros_time_) {
    resetState("ROS time jumped backwards by " + std::to_string((last_ros_time_ - now).toSec()) +
               " s (bag loop?)");
  }
  last_ros_time_ = now;
}

void GyroFlowRos::resetState(const std::string& why) {
  if (!why.empty()) {
    ROS_WARN_NAMED("gyro_flow", "%s: %s: clearing IMU buffer and frame history", log_name_.c_str(), why.c_str());
  }
  imu_buffer_.clear();
  lens_log_.clear();
  pending_frames_.clear();
  previous_.reset();
  // The IMU-to-camera rotation is kept (it is keyed by the two frame ids): the mount is rigid, and
  // a time jump makes tf2's listener clear its buffer, so a mount published on /tf (not latched
  // /tf_static) could otherwise not be found again after a bag loops.
  last_ros_time_ = ros::Time();
  time_base_.reset();
}

void GyroFlowRos::checkStampClock(const ros::Time& stamp, const std::string& topic) {
  const bool say = stamp_clock_.observe(stamp.toSec(), ros::Time::now().toSec());
  diagnostics_->setClockProblem(stamp_clock_.describe());
  // Once per timeline (the check starts over when time goes back): not throttled.
  if (say) ROS_WARN_NAMED("gyro_flow", "%s: %s: %s", log_name_.c_str(), topic.c_str(), stamp_clock_.describe().c_str());
}

double GyroFlowRos::secondsSinceBase(const ros::Time& stamp) {
  if (!time_base_) time_base_ = ros::Time(stamp.sec, 0);
  return (stamp - *time_base_).toSec();
}

void GyroFlowRos::imuCallback(const sensor_msgs::ImuConstPtr& imu) {
  std::lock_guard<std::mutex> lock(mutex_);
  runGuarded("gyro_flow", log_name_, imu_sub_.getTopic(), errors_, [&] { handleImu(imu); });
  reportSkips();
}

void GyroFlowRos::handleImu(const sensor_msgs::ImuConstPtr& imu) {
  checkRosTimeJump();
  checkStampClock(imu->header.stamp, imu_sub_.getTopic());
  ++imu_in_window_;
  if (imu->header.stamp > newest_imu_stamp_) newest_imu_stamp_ = imu->header.stamp;
  ++imu_received_;
  diagnostics_->tick("imu");
  last_imu_arrival_ = ros::Time::now();
  secondsSinceBase(imu->header.stamp);  // sets the time base on the first message
  const ImuSample sample = toImuSample(*imu, *time_base_);
  if (!imu_buffer_.empty() && sample.stamp_s < imu_buffer_.newestStamp() - params_.time_jump_reset_s) {
    resetState("IMU stamps on " + imu_sub_.getTopic() + " jumped backwards by " +
               std::to_string(imu_buffer_.newestStamp() - sample.stamp_s) + " s");
  }
  // Rates in different frames cannot be integrated together: the buffer holds one frame's samples.
  const std::string& frame_id = params_.imu_frame_id.empty() ? imu->header.frame_id : params_.imu_frame_id;
  if (!imu_buffer_.empty() && frame_id != imu_frame_id_) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: frame_id on %s changed from '%s' to '%s': clearing the IMU buffer", log_name_.c_str(),
                            imu_sub_.getTopic().c_str(), imu_frame_id_.c_str(), frame_id.c_str());
    imu_buffer_.clear();
  }
  const ImuAddResult added = imu_buffer_.add(sample);
  if (!added.accepted()) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: dropping IMU sample on %s: %s", log_name_.c_str(),
                            imu_sub_.getTopic().c_str(), added.reason.c_str());
    return;
  }
  imu_frame_id_ = frame_id;
  processPendingFrames();
}

void GyroFlowRos::lensShiftCallback(const LensShiftSampleConstPtr& sample) {
  std::lock_guard<std::mutex> lock(mutex_);
  runGuarded("gyro_flow", log_name_, lens_sub_.getTopic(), errors_, [&] { handleLensShift(sample); });
  reportSkips();
}

void GyroFlowRos::handleLensShift(const LensShiftSampleConstPtr& sample) {
  checkRosTimeJump();
  last_lens_arrival_ = ros::Time::now();
  secondsSinceBase(sample->header.stamp);  // sets the time base on the first message
  LensShiftLogSample logged;
  logged.stamp_s = (sample->header.stamp - *time_base_).toSec();
  logged.logged = Eigen::Vector2d(sample->x, sample->y);
  if (sample->covariance[0] >= 0.0) {
    logged.covariance = (Eigen::Matrix2d() << sample->covariance[0], sample->covariance[1],
                         sample->covariance[2], sample->covariance[3]).finished();
  }
  // A log that starts over (a bag loop, a camera restart) replaces the old one.
  if (!lens_log_.empty() &&
      logged.stamp_s < lens_log_.samples().back().stamp_s - params_.time_jump_reset_s) {
    ROS_WARN_NAMED("gyro_flow", "%s: stamps on %s jumped backwards by %.3f s: clearing the lens-shift log",
                   log_name_.c_str(), lens_sub_.getTopic().c_str(),
                   lens_log_.samples().back().stamp_s - logged.stamp_s);
    lens_log_.clear();
  }
  const LensShiftAddResult added = lens_log_.add(logged);
  if (!added.accepted()) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: dropping lens-shift sample on %s: %s",
                            log_name_.c_str(), lens_sub_.getTopic().c_str(), added.reason.c_str());
    return;
  }
  // Bounded memory: as much history as the IMU buffer keeps.
  lens_log_.dropBefore(lens_log_.newestStampS() - params_.imu_buffer_duration_s);
  processPendingFrames();
}

void GyroFlowRos::cameraCallback(const sensor_msgs::ImageConstPtr& image,
                                 const sensor_msgs::CameraInfoConstPtr& info) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::size_t errors_before = errors_;
  runGuarded("gyro_flow", log_name_, image_topic_, errors_, [&] { handleFrame(image, info); });
  if (errors_ != errors_before) skipPair("an error while handling the frame (warned)");
  reportSkips();
}

void GyroFlowRos::handleFrame(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info) {
  checkRosTimeJump();
  ++frames_received_;
  diagnostics_->tick("frames");
  ++frames_in_window_;
  const std::string& topic = image_topic_;
  // Without an image (~use_camera_info_only) the CameraInfo's header stands for the frame's.
  const std_msgs::Header& header = image ? image->header : info->header;
  if (header.stamp > newest_frame_stamp_) newest_frame_stamp_ = header.stamp;
  checkStampClock(header.stamp, topic);
  const double stamp_s = header.stamp.toSec();

  std::string problem = image ? validateImage(*image) : "";
  if (!problem.empty()) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: dropping frame %.6f on %s: %s", log_name_.c_str(),
                            stamp_s, topic.c_str(), problem.c_str());
    skipPair("frame refused: " + problem);
    return;
  }
  const std::uint32_t width = image ? image->width : info->width;
  const std::uint32_t height = image ? image->height : info->height;
  if (static_cast<double>(width) * height > params_.max_image_pixels) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: dropping frame %.6f on %s: %ux%u is more than ~max_image_pixels (%d) pixels", log_name_.c_str(),
                            stamp_s, topic.c_str(), width, height, params_.max_image_pixels);
    skipPair("frame larger than ~max_image_pixels");
    return;
  }
  Frame frame;
  std::string note;
  problem = toCameraModel(*info, frame.camera, &note);
  if (note != camera_info_note_) {  // said once per change, not per frame
    if (!note.empty()) ROS_WARN_NAMED("gyro_flow", "%s: %s: %s", log_name_.c_str(), info_topic_.c_str(), note.c_str());
    camera_info_note_ = note;
  }
  if (!problem.empty()) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: dropping frame %.6f: %s: %s", log_name_.c_str(),
                            stamp_s, info_topic_.c_str(), problem.c_str());
    skipPair("camera_info refused: " + problem);
    return;
  }
  if (image && (image->width != info->width || image->height != info->height)) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: dropping frame %.6f: image on %s is %ux%u but %s says %ux%u", log_name_.c_str(),
                            stamp_s, topic.c_str(), image->width, image->height,
                            info_topic_.c_str(), info->width, info->height);
    skipPair("image and camera_info sizes differ");
    return;
  }
  frame.stamp = header.stamp;
  frame.frame_id = params_.camera_frame_id.empty() ? header.frame_id : params_.camera_frame_id;
  frame.distortion_model = info->distortion_model;
  frame.distortion = info->D;
  frame.received = ros::Time::now();

  const ros::Time* latest = !pending_frames_.empty() ? &pending_frames_.back().stamp
                            : previous_                 ? &previous_->stamp
                                                        : nullptr;
  if (latest != nullptr && frame.stamp <= *latest) {
    const double back_s = (*latest - frame.stamp).toSec();
    if (back_s > params_.time_jump_reset_s) {
      resetState("camera stamps on " + topic + " jumped backwards by " + std::to_string(back_s) + " s");
    } else {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                              "%s: dropping frame %.6f on %s: %s stamp (latest frame %.6f)", log_name_.c_str(),
                              stamp_s, topic.c_str(), back_s == 0.0 ? "duplicate" : "out-of-order",
                              latest->toSec());
      skipPair(back_s == 0.0 ? "duplicate frame stamp" : "out-of-order frame stamp");
      return;
    }
  }
  pending_frames_.push_back(frame);
  if (pending_frames_.size() > kMaxPendingFrames) {
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: %zu frames wait for IMU data on %s: dropping the oldest", log_name_.c_str(),
                            pending_frames_.size(), imu_sub_.getTopic().c_str());
    skipPair("more than 60 frames waiting for IMU data");
    previous_ = pending_frames_.front();
    frames_dropped_since_previous_ = 0;
    pending_frames_.pop_front();
  }
  processPendingFrames();
}

void GyroFlowRos::cameraInfoCallback(const sensor_msgs::CameraInfoConstPtr& info) {
  cameraCallback(nullptr, info);
}

void GyroFlowRos::processPendingFrames() {
  while (!pending_frames_.empty()) {
    const Frame& frame = pending_frames_.front();
    if (previous_) {
      const Outcome outcome = processFrame(frame);
      if (outcome == Outcome::kWaitForImu || outcome == Outcome::kWaitForLensLog ||
          outcome == Outcome::kWaitForTransform) {
        return;
      }
    }
    // Published or dropped, this frame is the earlier frame of the next pair.
    if (previous_) pair_rules_.accepted((frame.stamp - previous_->stamp).toSec());
    previous_ = frame;
    frames_dropped_since_previous_ = 0;
    pending_frames_.pop_front();
  }
}

std::optional<Eigen::Matrix3d> GyroFlowRos::imuToCameraRotation(const Frame& frame, bool& wait) {
  wait = false;
  if (!params_.rotation_from_tf) return params_.rolling_shutter.imu_to_camera_rotation;
  const std::string& camera_frame = frame.frame_id;
  if (imu_frame_id_.empty() || camera_frame.empty()) {
    skipPair("empty frame_id: no IMU-to-camera transform can be looked up");
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: %s has an empty frame_id: set ~%s or ~imu_to_camera_rotation", log_name_.c_str(),
                            imu_frame_id_.empty() ? imu_sub_.getTopic().c_str() : image_topic_.c_str(),
                            imu_frame_id_.empty() ? "imu_frame_id" : "camera_frame_id");
    return std::nullopt;
  }
  // The IMU is rigidly mounted on the camera: one lookup per frame pair is plenty, and the
  // result is kept until the frames change or the state resets.
  const std::string frames = imu_frame_id_ + " -> " + camera_frame;
  if (cached_rotation_ && cached_rotation_frames_ == frames) return cached_rotation_;
  try {
    const geometry_msgs::TransformStamped transform =
        tf_buffer_.lookupTransform(camera_frame, imu_frame_id_, ros::Time(0));
    const auto& q = transform.transform.rotation;
    cached_rotation_ = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
    cached_rotation_frames_ = frames;
    return cached_rotation_;
  } catch (const tf2::TransformException& e) {
    // Start-up: the mount's latched /tf_static travels on its own connection, which a player or a
    // driver may open after the sensor data flows (rosbag play advertises it last when started
    // past it), so the first frames can come before it. Until the rotation has been found once,
    // a frame waits for it as for its IMU samples (bounded by ~imu_wait_timeout) instead of
    // losing its pair (issue 14, defect 9).
    if (!cached_rotation_ && (ros::Time::now() - frame.received).toSec() < params_.imu_wait_timeout_s) {
      wait = true;
      return std::nullopt;
    }
    // Say what tf knows: nothing at all (no /tf_static received: the publisher is not running, or
    // its latched message has not arrived yet), or other frames (a wrong frame_id).
    std::vector<std::string> known;
    tf_buffer_._getFrameStrings(known);
    std::string known_text;
    for (const std::string& f : known) known_text += (known_text.empty() ? "" : ", ") + f;
    const std::string what = known.empty() ? "tf has received no transform at all yet" : "tf knows " + known_text;
    skipPair("no IMU-to-camera transform " + frames + " in tf (" + what + ")");
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: no IMU-to-camera transform %s in tf (%s; %s); set "
                            "~imu_to_camera_rotation or publish it on /tf_static", log_name_.c_str(),
                            frames.c_str(), e.what(), what.c_str());
    return std::nullopt;
  }
}

GyroFlowRos::Outcome GyroFlowRos::processFrame(const Frame& frame) {
  const Frame& previous = *previous_;
  const double interval_s = (frame.stamp - previous.stamp).toSec();
  pair_rules_.setLimits(FramePairLimits{params_.max_frame_interval_s, params_.imu_wait_timeout_s,
                                        params_.lens_shift_wait_timeout_s});
  switch (pair_rules_.check(secondsSinceBase(previous.stamp), secondsSinceBase(frame.stamp),
                            frame.camera == previous.camera)) {
    case FramePairCheck::kPair:
      break;
    case FramePairCheck::kTooFarApart:
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                              "%s: frames %.6f and %.6f on %s are %.1f ms apart (> ~max_frame_interval "
                              "%.1f ms): not pairing them", log_name_.c_str(),
                              previous.stamp.toSec(), frame.stamp.toSec(), image_topic_.c_str(),
                              interval_s * 1e3, params_.max_frame_interval_s * 1e3);
      skipPair("frames further apart than ~max_frame_interval");
      return Outcome::kDropped;
    case FramePairCheck::kCameraChanged:
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                              "%s: %s changed between frames %.6f and %.6f: not pairing them", log_name_.c_str(),
                              info_topic_.c_str(), previous.stamp.toSec(), frame.stamp.toSec());
      skipPair("camera_info changed between the frames");
      return Outcome::kDropped;
  }
  bool wait_for_transform = false;
  const std::optional<Eigen::Matrix3d> rotation = imuToCameraRotation(frame, wait_for_transform);
  if (wait_for_transform) return Outcome::kWaitForTransform;
  if (!rotation) return Outcome::kDropped;  // imuToCameraRotation counted it
  diagnostics_->setValue("R_cam_imu source", params_.rotation_from_tf ? "tf " + cached_rotation_frames_
                                                                       : "~imu_to_camera_rotation");

  RollingShutterConfig config = params_.rolling_shutter;
  config.imu_to_camera_rotation = *rotation;
  // A drifting clock (the online calibration's line): the offset at frame b, so that it follows the
  // drift between calibrations. Within an epoch it changes by the drift alone (microseconds a
  // frame), as a drifting clock does; a consumer sees a continuous offset, not a jump.
  config.time_offset_s = timeOffsetOnLine(config.time_offset_s, params_.time_offset_rate,
                                         params_.time_offset_reference_s, frame.stamp.toSec());
  // Each move of a drifting offset is a calibration change for a consumer keeping state along the
  // stream: frame a of this pair is frame b of the last one, now at an IMU time moved by the
  // drift (microseconds). Without a new epoch a negative rate reads as time going back by that
  // much, and the compensation restarted its model on every pair (the drifting-clock soak).
  if (params_.time_offset_rate != 0.0 && config.time_offset_s != last_pair_time_offset_s_) ++calibration_epoch_;
  last_pair_time_offset_s_ = config.time_offset_s;
  // The pair for the frame-pair processor: its first step (the gyro's motion) runs here, alone,
  // because the pair may have to wait for IMU data and then for the lens log between the steps.
  FramePair pair;
  pair.stamp_a_s = secondsSinceBase(previous.stamp);
  pair.stamp_b_s = secondsSinceBase(frame.stamp);
  pair.timing = config;
  pair.camera = &frame.camera;
  pair.imu = &imu_buffer_;
  pair.integration = params_.integration;
  RollingShutterHomographies result = FramePairProcessor::gyroMotion(pair);
  if (!result.ok()) {
    const ros::Time now = ros::Time::now();
    const double waited_s = (now - frame.received).toSec();
    const double imu_quiet_s = last_imu_arrival_.isZero() ? -1.0 : (now - last_imu_arrival_).toSec();
    if (pair_rules_.imuWait(result.status, waited_s, imu_quiet_s) == FrameWait::kWait) return Outcome::kWaitForImu;
    const bool may_still_come = FramePairRules::imuMayStillCome(result.status);
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: dropping frame %.6f: %s on %s%s", log_name_.c_str(),
                            frame.stamp.toSec(), result.reason.c_str(), imu_sub_.getTopic().c_str(),
                            may_still_come ? " (waited ~imu_wait_timeout)" : "");
    // The tally groups by kind (the warning above has the stamps).
    const std::string kind = result.status == IntegrationStatus::kTooOld
                                 ? "the pair starts before the oldest IMU sample (stream start, loop, or lagging frames)"
                                 : std::string(toString(result.status));
    skipPair("IMU not covering the pair: " + kind +
             (may_still_come ? " (waited ~imu_wait_timeout)" : ""));
    return Outcome::kDropped;
  }
  // A pair longer than the camera's usual interval lost a frame in between: say so (it still
  // is a right flow between these two frames).
  if (const int spans = pair_rules_.spannedIntervals(interval_s); spans > 0) {
    const std::string where = frames_dropped_since_previous_ > 0
                                  ? "frame(s) between them were dropped here (see the warnings)"
                                  : "frame(s) between them never reached this nodelet (lost upstream, or a full "
                                    "~image_queue_size subscriber queue)";
    ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                            "%s: the flow from %.6f to %.6f on %s spans %d frame intervals (%.1f ms, usual "
                            "%.1f ms): %s", log_name_.c_str(),
                            previous.stamp.toSec(), frame.stamp.toSec(), image_topic_.c_str(), spans,
                            interval_s * 1e3, pair_rules_.typicalIntervalS() * 1e3, where.c_str());
    skipPair("flow spanning " + std::to_string(spans) + " frame intervals (published)");
  }

  // The lens log, when the camera has one: wait while it may still come (a phone delivers it with
  // the capture result, after the frame), then use it if it covers the pair, else the gyro alone.
  // The wait is bounded per frame, so a log on a wrong clock delays pairs but never drops them.
  if (params_.use_lens_shift_log && !lens_log_.empty()) {
    lens_log_.setConvention(params_.lens_shift_convention);
    const LensLogInterval needed = lensLogInterval(config, pair.stamp_a_s, pair.stamp_b_s);
    const ros::Time now = ros::Time::now();
    if (pair_rules_.lensLogWait(lens_log_.newestStampS(), needed.end_s, (now - frame.received).toSec(),
                                (now - last_lens_arrival_).toSec()) == FrameWait::kWait) {
      return Outcome::kWaitForLensLog;
    }
    pair.lens_log = &lens_log_;
  }
  // The rest of the recipe: the lens log where it covers the pair, and the flow on the grid.
  pair.rotations = std::move(result.rotations);
  pair.gyro_homographies = std::move(result.homographies);
  const bool lens_log_given = pair.lens_log != nullptr;
  FramePairMotion motion = processor_.process(std::move(pair), params_.grid_size);
  const bool with_lens_log = motion.source == PairMotionSource::kLensLog;
  if (lens_log_given) countLensLogUse(previous, frame, config, motion);
  const std::vector<Eigen::Matrix3d>& homographies = motion.homographies;
  const cv::Mat& flow = motion.flow;

  GyroFlowMetadata metadata;
  metadata.header.stamp = frame.stamp;
  metadata.header.frame_id = frame.frame_id;
  metadata.previous_stamp = previous.stamp;
  metadata.camera = frame.camera;
  metadata.distortion_model = frame.distortion_model;
  metadata.distortion = frame.distortion;
  metadata.rolling_shutter = config;
  metadata.calibration_epoch = calibration_epoch_;
  {
    // The gyro stream behind the pair (for stabiliser models downstream): from the model's warm-up
    // before frame a's first patch to frame b's last patch, relative to frame b's stamp. Every
    // message carries the warm-up, so a consumer that starts (or restarts) anywhere in the stream
    // starts from the same history as the evaluator; later messages only add their newest samples.
    const double stamp_a_s = secondsSinceBase(previous.stamp), stamp_b_s = secondsSinceBase(frame.stamp);
    for (CameraRateSample rate : pairGyroStream(imu_buffer_, config, stamp_a_s, stamp_b_s)) {
      rate.stamp_s -= stamp_b_s;
      metadata.camera_rates.push_back(rate);
    }
  }
  GyroFlowPtr msg;
  if (flow_pub_.getNumSubscribers() > 0) {
    msg = boost::make_shared<GyroFlow>();
    fillGyroFlowMsg(metadata, homographies, flow, *msg);
    msg->motion_model = with_lens_log ? GyroFlow::MOTION_GYRO_LENS_LOG : GyroFlow::MOTION_GYRO;
    // Every field checked before anything of the pair goes out (the inputs were checked one by one).
    const std::string problem = gyroFlowProblem(*msg);
    if (!problem.empty()) {
      ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow", "%s: not publishing the flow %.6f -> %.6f on %s: %s",
                              log_name_.c_str(), previous.stamp.toSec(), frame.stamp.toSec(),
                              flow_pub_.getTopic().c_str(), problem.c_str());
      skipPair("an output that failed validation (warned)");
      return Outcome::kDropped;
    }
    flow_pub_.publish(msg);
  }
  if (color_pub_.getNumSubscribers() > 0) {
    const cv::Mat rgb = colorizeFlow(flow, params_.color_max_flow_px);
    color_pub_.publish(cv_bridge::CvImage(metadata.header, sensor_msgs::image_encodings::RGB8, rgb).toImageMsg());
  }
  flow_image_pub_.publish(metadata.header, flow);
  ++flows_published_;
  diagnostics_->tick("gyro flows");
  diagnostics_->latency((ros::Time::now() - frame.stamp).toSec());
  ++flows_in_window_;
  return Outcome::kPublished;
}

void GyroFlowRos::countLensLogUse(const Frame& previous, const Frame& frame, const RollingShutterConfig& config,
                                  const FramePairMotion& motion) {
  const double stamp_a_s = secondsSinceBase(previous.stamp), stamp_b_s = secondsSinceBase(frame.stamp);
  if (motion.source == PairMotionSource::kLensLog) {
    ++lens_log_pairs_;
    diagnostics_->setValue("pairs with the lens-shift log", std::to_string(lens_log_pairs_));
    // The next pair starts at this frame: older samples are not needed any more.
    lens_log_.dropBefore(lensLogInterval(config, stamp_a_s, stamp_b_s).begin_s);
    return;
  }
  ++lens_fallback_pairs_;
  diagnostics_->setValue("pairs the lens-shift log did not cover", std::to_string(lens_fallback_pairs_));
  ROS_WARN_THROTTLE_NAMED(kWarnPeriodS, "gyro_flow",
                          "%s: the lens-shift log on %s does not cover frames %.6f -> %.6f (%s; ~lens_shift_max_gap "
                          "%g s): gyro homographies without the lens for this pair (motion_model '%s'; %zu such "
                          "pair(s) since start, %zu with the log)",
                          log_name_.c_str(), lens_sub_.getTopic().c_str(), previous.stamp.toSec(),
                          frame.stamp.toSec(), motion.reason.c_str(), params_.lens_shift_max_gap_s,
                          GyroFlow::MOTION_GYRO.c_str(), lens_fallback_pairs_, lens_log_pairs_);
}

void GyroFlowRos::skipPair(const std::string& reason) {
  skipped_.add(reason);
  diagnostics_->drop(reason);
  window_problem_ = reason;
  if (reason.find("(published)") == std::string::npos) ++frames_dropped_since_previous_;
}

void GyroFlowRos::reportSkips() {
  const ros::WallTime now = ros::WallTime::now();
  if (!skipped_.pending() || (now - last_skip_report_).toSec() < kWarnPeriodS) return;
  last_skip_report_ = now;
  const std::size_t count = skipped_.pendingCount();
  ROS_WARN_NAMED("gyro_flow",
                 "%s: %zu frame pair(s) on %s skipped or spanning lost frames since the last report (%zu "
                 "since start): %s", log_name_.c_str(),
                 count, image_topic_.c_str(), skipped_.total(), skipped_.take().c_str());
}

void GyroFlowRos::waitingTimerCallback(const ros::WallTimerEvent&) {
  std::lock_guard<std::mutex> lock(mutex_);
  runGuarded("gyro_flow", log_name_, imu_sub_.getTopic(), errors_, [&] { checkProgress(); });
}

void GyroFlowRos::checkProgress() {
  reportSkips();  // also when no callback runs any more
  if (!imu_sub_) return;
  const std::size_t imu = imu_in_window_, frames = frames_in_window_, flows = flows_in_window_;
  const std::string problem = window_problem_;
  imu_in_window_ = frames_in_window_ = flows_in_window_ = 0;
  window_problem_.clear();
  // Copies: getTopic() returns by value.
  const std::string imu_topic_s = imu_sub_.getTopic(), image_topic_s = image_topic_,
                    info_topic_s = info_topic_;
  const char* imu_topic = imu_topic_s.c_str();
  const char* image_topic = image_topic_s.c_str();
  const char* info_topic = info_topic_s.c_str();
  if (flows > 0) {
    input_stopped_reported_ = false;
    return;
  }
  if (imu == 0 && frames == 0) {
    if (imu_received_ == 0 && frames_received_ == 0) {
      ROS_WARN_NAMED("gyro_flow",
                     "%s: still waiting for sensor_msgs/Imu on %s and images on %s with camera_info on %s", log_name_.c_str(),
                     imu_topic, image_topic, info_topic);
    } else if (!input_stopped_reported_) {
      // Once: a bag that ended or a stopped camera is not an error to repeat every few seconds.
      ROS_WARN_NAMED("gyro_flow",
                     "%s: no input on %s or %s in the last %.0f s (stream stopped or bag ended): waiting", log_name_.c_str(),
                     imu_topic, image_topic, kWaitingCheckPeriodS);
      input_stopped_reported_ = true;
    }
    return;
  }
  input_stopped_reported_ = false;
  if (imu == 0) {
    ROS_WARN_NAMED("gyro_flow",
                   "%s: %zu frames on %s but no sensor_msgs/Imu on %s in the last %.0f s: no flow without "
                   "gyro data", log_name_.c_str(),
                   frames, image_topic, imu_topic, kWaitingCheckPeriodS);
  } else if (frames == 0) {
    ROS_WARN_NAMED("gyro_flow",
                   "%s: %zu IMU samples on %s but no frames in the last %.0f s: are images published on %s "
                   "with camera_info of the same stamps on %s?", log_name_.c_str(),
                   imu, imu_topic, kWaitingCheckPeriodS, image_topic, info_topic);
  } else if (!problem.empty()) {
    ROS_WARN_NAMED("gyro_flow",
                   "%s: %zu IMU samples and %zu frames in the last %.0f s but no flow published; latest "
                   "reason: %s", log_name_.c_str(),
                   imu, frames, kWaitingCheckPeriodS, problem.c_str());
  } else {
    ROS_WARN_NAMED("gyro_flow",
                   "%s: %zu IMU samples and %zu frames in the last %.0f s but no flow published: %zu "
                   "frame(s) wait for IMU samples covering them (newest IMU stamp %.3f, newest frame %.3f; "
                   "~time_offset %.4f s)", log_name_.c_str(),
                   imu, frames, kWaitingCheckPeriodS, pending_frames_.size(), newest_imu_stamp_.toSec(),
                   newest_frame_stamp_.toSec(), params_.rolling_shutter.time_offset_s);
  }
}

}  // namespace deep_ois
