#include "deep_ois/ros/live/gyro_flow_parameters.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {

namespace {

[[noreturn]] void reject(const ParameterSource& nh, const std::string& name, const std::string& what) {
  throw std::invalid_argument("parameter " + nh.describe(name) + ": " + what);
}

double positiveSeconds(const ParameterSource& nh, const std::string& name, double fallback) {
  const double value = nh.param(name, fallback);
  if (!std::isfinite(value) || value <= 0.0) {
    reject(nh, name, "must be a positive number of seconds, got " + std::to_string(value));
  }
  return value;
}

}  // namespace

GyroFlowParameters loadGyroFlowParameters(const ros::NodeHandle& private_nh) {
  return loadGyroFlowParameters(NodeHandleParameters(private_nh));
}

GyroFlowParameters loadGyroFlowParameters(const ParameterSource& nh) {
  GyroFlowParameters p;
  RollingShutterConfig& rs = p.rolling_shutter;

  rs.patch_count = nh.param("patch_count", 6);
  if (rs.patch_count < 1 || rs.patch_count > 1000) {
    reject(nh, "patch_count", "must be between 1 and 1000, got " + std::to_string(rs.patch_count));
  }
  rs.readout_time_s = nh.param("readout_time", 0.0);
  if (!std::isfinite(rs.readout_time_s) || rs.readout_time_s < 0.0 || rs.readout_time_s > 1.0) {
    reject(nh, "readout_time", "must be between 0 and 1 s, got " + std::to_string(rs.readout_time_s));
  }
  rs.time_offset_s = nh.param("time_offset", 0.0);
  if (!std::isfinite(rs.time_offset_s) || std::abs(rs.time_offset_s) > 10.0) {
    reject(nh, "time_offset", "must be within +-10 s, got " + std::to_string(rs.time_offset_s));
  }
  const std::string patch_time = nh.param<std::string>("patch_time", "centre");
  if (patch_time == "centre" || patch_time == "center") {
    rs.patch_time = PatchTimeReference::kPatchCentre;
  } else if (patch_time == "start") {
    rs.patch_time = PatchTimeReference::kPatchStart;
  } else {
    reject(nh, "patch_time", "must be 'centre' or 'start', got '" + patch_time + "'");
  }

  std::vector<double> rotation;
  if (nh.get("imu_to_camera_rotation", rotation) && !rotation.empty()) {
    if (rotation.size() != 9) {
      reject(nh, "imu_to_camera_rotation",
             "must hold 9 numbers (row-major R_cam_imu), got " + std::to_string(rotation.size()));
    }
    rs.imu_to_camera_rotation = rowMajorToMatrix(rotation.data());
    p.rotation_from_tf = false;
  }
  const std::string rs_problem = rs.validate();
  if (!rs_problem.empty()) reject(nh, "imu_to_camera_rotation", rs_problem);

  const std::string interpolation = nh.param<std::string>("interpolation", "linear");
  if (interpolation == "linear") {
    p.integration.interpolation = RateInterpolation::kLinear;
  } else if (interpolation == "zero_order_hold") {
    p.integration.interpolation = RateInterpolation::kZeroOrderHold;
  } else {
    reject(nh, "interpolation", "must be 'linear' or 'zero_order_hold', got '" + interpolation + "'");
  }
  std::vector<double> bias;
  if (nh.get("gyro_bias", bias) && !bias.empty()) {
    if (bias.size() != 3 || !std::isfinite(bias[0] + bias[1] + bias[2])) {
      reject(nh, "gyro_bias", "must hold 3 finite numbers in rad/s (IMU frame)");
    }
    p.integration.gyro_bias_rad_s = Eigen::Vector3d(bias[0], bias[1], bias[2]);
  }
  p.integration.max_sample_gap_s = positiveSeconds(nh, "max_imu_gap", 0.05);
  p.follow_online_calibration = nh.param("follow_online_calibration", p.follow_online_calibration);

  p.camera_frame_id = nh.param<std::string>("camera_frame_id", "");
  p.imu_frame_id = nh.param<std::string>("imu_frame_id", "");

  const int grid_width = nh.param("grid_width", 360);
  const int grid_height = nh.param("grid_height", 270);
  if (grid_width < 1 || grid_height < 1 || grid_width > 8192 || grid_height > 8192) {
    reject(nh, "grid_width/grid_height", "must be between 1 and 8192 pixels, got " +
                                             std::to_string(grid_width) + "x" + std::to_string(grid_height));
  }
  p.grid_size = cv::Size(grid_width, grid_height);
  p.color_max_flow_px = nh.param("color_max_flow", 0.0);
  if (!std::isfinite(p.color_max_flow_px) || p.color_max_flow_px < 0.0) {
    reject(nh, "color_max_flow", "must be >= 0 pixels (0 = scale each frame by its largest flow)");
  }

  p.imu_buffer_duration_s = positiveSeconds(nh, "imu_buffer_duration", 5.0);
  p.imu_wait_timeout_s = positiveSeconds(nh, "imu_wait_timeout", 0.5);
  p.max_frame_interval_s = positiveSeconds(nh, "max_frame_interval", 0.25);
  p.time_jump_reset_s = positiveSeconds(nh, "time_jump_reset", 1.0);
  if (p.imu_buffer_duration_s < 2.0 * p.max_frame_interval_s) {
    reject(nh, "imu_buffer_duration", "must cover at least two frame intervals (2 x max_frame_interval)");
  }
  p.use_camera_info_only = nh.param("use_camera_info_only", false);
  p.image_queue_size = nh.param("image_queue_size", p.image_queue_size);
  p.max_image_pixels = nh.param("max_image_pixels", p.max_image_pixels);
  if (p.max_image_pixels < 1) reject(nh, "max_image_pixels", "must be at least 1 pixel");
  p.imu_queue_size = nh.param("imu_queue_size", 2000);
  if (p.image_queue_size < 1 || p.imu_queue_size < 1) {
    reject(nh, "image_queue_size/imu_queue_size", "must be at least 1");
  }

  p.use_lens_shift_log = nh.param("use_lens_shift_log", true);
  LensShiftLogConvention& lens = p.lens_shift_convention;
  lens.scale = nh.param("lens_shift_scale", 1.0);
  lens.swap_xy = nh.param("lens_shift_swap_xy", false);
  lens.sign_x = nh.param("lens_shift_sign_x", 1.0);
  lens.sign_y = nh.param("lens_shift_sign_y", 1.0);
  lens.time_offset_s = nh.param("lens_shift_time_offset", 0.0);
  const std::string lens_problem = lens.validate();
  if (!lens_problem.empty()) reject(nh, "lens_shift_" + lens_problem.substr(0, lens_problem.find(' ')), lens_problem);
  p.lens_shift_max_gap_s = positiveSeconds(nh, "lens_shift_max_gap", 0.02);
  p.lens_shift_wait_timeout_s = positiveSeconds(nh, "lens_shift_wait_timeout", 0.2);
  p.lens_shift_queue_size = nh.param("lens_shift_queue_size", 1000);
  if (p.lens_shift_queue_size < 1) reject(nh, "lens_shift_queue_size", "must be at least 1");
  return p;
}

}  // namespace deep_ois
