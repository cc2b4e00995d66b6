// ROS wrapper of the gyro flow: buffers sensor_msgs/Imu and, for every camera frame, publishes the
// rolling-shutter homographies and dense flow between the previous frame and this one.
#pragma once

#include <deep_ois/GyroFlow.h>
#include <deep_ois/OnlineCalibration.h>
#include <deep_ois/LensShiftSample.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/common/drop_tally.h"
#include "deep_ois/core/common/stamp_clock_check.h"
#include "deep_ois/core/gyro/frame_pair_rules.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/flow_image_publisher.h"
#include "deep_ois/ros/live/gyro_flow_reconfigure.h"
#include "deep_ois/ros/live/live_diagnostics.h"

namespace deep_ois {

// Topics (relative to the node handle): subscribes `imu`, `image_raw` + `camera_info`
// (image_transport, transport chosen by ~image_transport) and, with ~use_lens_shift_log, the
// camera's lens-shift log `lens_shift` (deep_ois/LensShiftSample); publishes `gyro_flow`
// (deep_ois/GyroFlow) and `gyro_flow/color` (rgb8). Inputs are subscribed only while an output
// has a subscriber.
//
// Threading: every subscription callback and the timer run on the node handle's callback queue;
// subscriber-status callbacks come from publisher threads. One mutex guards all state, so the
// class is safe with single- or multi-threaded handles. Processing a frame takes about a
// millisecond, so holding the mutex through it costs nothing.
class GyroFlowRos {
 public:
  // Reads the parameters from `private_nh`; throws std::invalid_argument naming a bad parameter.
  GyroFlowRos(ros::NodeHandle nh, ros::NodeHandle private_nh);
  ~GyroFlowRos();

  GyroFlowRos(const GyroFlowRos&) = delete;
  GyroFlowRos& operator=(const GyroFlowRos&) = delete;

 private:
  // A frame waiting for the IMU samples that cover it.
  struct Frame {
    ros::Time stamp;
    std::string frame_id;
    CameraModel camera;
    std::string distortion_model;
    std::vector<double> distortion;  // CameraInfo D as received
    ros::Time received;  // ROS time of arrival, to bound the wait for IMU data
  };

  void connectCallback();
  void imuCallback(const sensor_msgs::ImuConstPtr& imu);
  void lensShiftCallback(const LensShiftSampleConstPtr& sample);
  // `image` is null with ~use_camera_info_only: the CameraInfo alone describes the frame.
  void cameraCallback(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  void cameraInfoCallback(const sensor_msgs::CameraInfoConstPtr& info);
  void waitingTimerCallback(const ros::WallTimerEvent&);
  // The compensation's online calibration: a new version for this camera is applied through the
  // reconfigure server (as a dynparam client would), so dynparam get shows the values in use.
  void onlineCalibrationCallback(const OnlineCalibrationConstPtr& msg);
  // The callbacks' work, inside runGuarded.
  void handleImu(const sensor_msgs::ImuConstPtr& imu);
  void handleLensShift(const LensShiftSampleConstPtr& sample);
  void handleFrame(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  // The watchdog: says, per window, why nothing was published (once when the input stopped).
  void checkProgress();

  // Pairs pending frames with the previous frame as far as the IMU data allows.
  void processPendingFrames();
  // Publishes the gyro flow from previous_ to `frame`; false when IMU data is not there yet.
  enum class Outcome { kPublished, kWaitForImu, kWaitForLensLog, kWaitForTransform, kDropped };
  Outcome processFrame(const Frame& frame);
  // Counts a pair given the lens log: with it (older samples then dropped), or without it, with
  // a throttled warning saying why the pair fell back to the gyro alone.
  void countLensLogUse(const Frame& previous, const Frame& frame, const RollingShutterConfig& config,
                       const FramePairMotion& motion);
  // Counts a frame pair that gives no flow, with the reason (also the watchdog's latest problem).
  void skipPair(const std::string& reason);
  // The throttled warning of every pair skipped since the last one.
  void reportSkips();
  // Says once (per timeline) when the stamps on `topic` are far from ROS time (use_sim_time).
  void checkStampClock(const ros::Time& stamp, const std::string& topic);
  // R_cam_imu from the parameter or tf for `frame`. Empty when unavailable: then either `wait` is
  // set (no rotation found yet since the start and the frame has waited less than
  // ~imu_wait_timeout: at start-up a latched /tf_static can arrive after the first frames), or
  // the pair is counted as skipped with a throttled warning.
  std::optional<Eigen::Matrix3d> imuToCameraRotation(const Frame& frame, bool& wait);
  // Forgets IMU samples and frames, e.g. when time jumps backwards because a bag loops.
  void resetState(const std::string& why);
  // Resets when ROS time went backwards since the last callback.
  void checkRosTimeJump();

  ros::NodeHandle nh_;
  ros::NodeHandle private_nh_;
  // The nodelet's resolved name (e.g. /deep_ois/gyro_flow), first in every log line: two cameras
  // in one manager are told apart.
  std::string log_name_;
  // Replaced as a whole (under mutex_) when dynamic_reconfigure changes a live-tunable value.
  GyroFlowParameters params_;

  std::mutex mutex_;
  image_transport::ImageTransport it_;
  ros::Subscriber imu_sub_;
  image_transport::CameraSubscriber camera_sub_;
  ros::Subscriber info_sub_;  // instead of camera_sub_ with ~use_camera_info_only
  ros::Subscriber lens_sub_;  // the camera's lens-shift log, with ~use_lens_shift_log
  ros::Subscriber calibration_sub_;  // online_calibration, with ~follow_online_calibration
  OnlineCalibrationConstPtr calibration_applied_;  // the message last applied (its callback only)
  std::string image_topic_, info_topic_;  // resolved input topics, for messages
  ros::Publisher flow_pub_;
  image_transport::Publisher color_pub_;
  FlowImagePublisher flow_image_pub_;  // gyro_flow/image: the flow as a plain 32FC2 image
  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::WallTimer waiting_timer_;
  std::unique_ptr<LiveDiagnostics> diagnostics_;  // /diagnostics: rates, drops, latency, calibration
  std::unique_ptr<GyroFlowReconfigure> reconfigure_;

  ImuSampleBuffer imu_buffer_;
  std::string imu_frame_id_;  // frame of every sample in imu_buffer_
  std::deque<Frame> pending_frames_;
  // Lens-shift samples as logged (stamps in seconds since time_base_, on the log's clock).
  LensShiftLog lens_log_;
  ros::Time last_lens_arrival_;       // ROS time the latest lens sample was handled
  std::size_t lens_log_pairs_ = 0;    // pairs published with the lens log since start
  std::size_t lens_fallback_pairs_ = 0;  // pairs with a log that did not cover them (gyro alone)
  std::optional<Frame> previous_;
  // The per-pair recipe (no stabiliser model here: the gyro, or the lens log where it covers the
  // pair), with the flow renderer it keeps per camera and grid.
  FramePairProcessor processor_;
  std::optional<Eigen::Matrix3d> cached_rotation_;     // tf rotation for cached_rotation_frames_
  std::string cached_rotation_frames_;
  ros::Time last_ros_time_;
  std::string camera_info_note_;  // the last warning about CameraInfo R and P (said once)
  // Origin of the seconds handed to the core (whole second of the first stamp since a reset).
  std::optional<ros::Time> time_base_;
  double secondsSinceBase(const ros::Time& stamp);

  // Pairs without a flow, and flows spanning more than one frame interval, by reason.
  DropTally skipped_;
  ros::WallTime last_skip_report_;
  std::size_t frames_dropped_since_previous_ = 0;  // frames refused here since previous_
  FramePairRules pair_rules_;                     // pairing, wait rules, typical frame interval
  StampClockCheck stamp_clock_;                   // input stamps against ROS time
  std::size_t errors_ = 0;                        // exceptions caught at the callbacks

  // Counters for the watchdog: since start, and in the current window.
  std::size_t imu_received_ = 0;
  ros::Time last_imu_arrival_;  // ROS time the latest IMU message was handled
  std::size_t frames_received_ = 0;
  std::size_t flows_published_ = 0;
  // GyroFlow.calibration_epoch: +1 per change of the calibration in use (reconfigure or online).
  std::uint32_t calibration_epoch_ = 0;
  double last_pair_time_offset_s_ = 0.0;  // the offset the last pair was made with (a drifting one moves)
  std::size_t imu_in_window_ = 0, frames_in_window_ = 0, flows_in_window_ = 0;
  std::string window_problem_;          // the latest reason a pair gave no flow in the window
  bool input_stopped_reported_ = false;  // said once when the input stops, until it resumes
  ros::Time newest_imu_stamp_, newest_frame_stamp_;
};

}  // namespace deep_ois
