// Every parameter of the gyro flow wrapper, read and validated in one place.
#pragma once

#include <ros/node_handle.h>

#include "deep_ois/ros/live/parameter_source.h"

#include <opencv2/core.hpp>
#include <string>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

struct GyroFlowParameters {
  // Rolling-shutter model. rolling_shutter.imu_to_camera_rotation is only used when
  // rotation_from_tf is false (the ~imu_to_camera_rotation parameter was given).
  RollingShutterConfig rolling_shutter;
  bool rotation_from_tf = true;
  IntegrationOptions integration;

  // ~follow_online_calibration: apply the compensation's online calibration (topic
  // online_calibration, deep_ois/OnlineCalibration) through the dynamic_reconfigure server: time
  // offset, readout, gyro bias, and the mount when the compensation estimates it.
  bool follow_online_calibration = true;
  // The online calibration's clock drift: a pair is made with the offset
  // rolling_shutter.time_offset_s + time_offset_rate * (frame b's stamp - time_offset_reference_s).
  // Only the online calibration sets a rate; an offset set by hand (parameter, reconfigure) is
  // constant (rate 0).
  double time_offset_rate = 0.0;          // s/s
  double time_offset_reference_s = 0.0;  // camera clock (the frames' ROS stamps), seconds

  std::string camera_frame_id;  // overrides the image's frame_id when not empty
  std::string imu_frame_id;     // overrides the Imu message's frame_id when not empty

  cv::Size grid_size{360, 270};        // working grid of the published flow, pixels
  double color_max_flow_px = 0.0;      // flow magnitude shown at full brightness; 0 = per frame max
  double imu_buffer_duration_s = 5.0;  // how much IMU history is kept
  double imu_wait_timeout_s = 0.5;     // how long a frame may wait for IMU samples covering it
  double max_frame_interval_s = 0.25;  // frames further apart are not paired (dropped frames)
  double time_jump_reset_s = 1.0;      // a stamp this much older than the newest one resets state
  // Subscribe camera_info alone (stamp, size, intrinsics), not the images: ~use_camera_info_only.
  bool use_camera_info_only = false;
  // Frames larger than this are refused (3840x2160, 4K UHD, the largest common video mode).
  int max_image_pixels = 3840 * 2160;
  int image_queue_size = 30;  // a second of 30 fps: a stalled thread does not lose frames
  int imu_queue_size = 2000;

  // The camera's own lens-shift log (topic `lens_shift`, deep_ois/LensShiftSample): a pair it
  // covers gets K(s(t_b)) R K(s(t_a))^-1 per patch instead of K R K^-1. See docs/lens_shift_logs.md.
  bool use_lens_shift_log = true;
  LensShiftLogConvention lens_shift_convention;  // ~lens_shift_scale, _swap_xy, _sign_x/y, _time_offset
  double lens_shift_max_gap_s = 0.02;            // a longer gap between samples is not bridged
  // How long a frame may wait for lens samples that cover it while the log is live, seconds.
  double lens_shift_wait_timeout_s = 0.2;
  int lens_shift_queue_size = 1000;
};

// Reads every parameter with its default. Throws std::invalid_argument with a message naming the
// parameter, its value and what is expected when one is invalid. The nodelet reads its private
// namespace; offline tools read config/gyro_flow.yaml through a YamlParameters source.
GyroFlowParameters loadGyroFlowParameters(const ParameterSource& source);
GyroFlowParameters loadGyroFlowParameters(const ros::NodeHandle& private_nh);

}  // namespace deep_ois
