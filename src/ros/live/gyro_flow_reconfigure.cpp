#include "deep_ois/ros/live/gyro_flow_reconfigure.h"

#include <ros/console.h>

#include <cmath>
#include <cstdio>
#include <sstream>

#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

namespace {

// "r00 r01 ... r22" (spaces or commas) -> R; empty text when it is not 9 numbers of a rotation.
std::string parseRotation(const std::string& text, Eigen::Matrix3d& R) {
  std::string spaced = text;
  for (char& c : spaced)
    if (c == ',' || c == '[' || c == ']') c = ' ';
  std::istringstream in(spaced);
  std::vector<double> values;
  for (double v; in >> v;) values.push_back(v);
  if (!in.eof() || values.size() != 9)
    return "r_cam_imu must be 9 numbers (row-major R_cam_imu) or empty (tf), got '" + text + "'";
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = values[static_cast<std::size_t>(3 * r + c)];
  if (!isProperRotation(R)) return "r_cam_imu is not a rotation (orthonormal, det +1): '" + text + "'";
  return "";
}

}  // namespace

std::string applyGyroFlowConfig(const GyroFlowConfig& config, GyroFlowParameters& params) {
  // The same bounds as the loader (loadGyroFlowParameters); the .cfg ranges already clamp most.
  if (!std::isfinite(config.time_offset) || std::abs(config.time_offset) > 10.0) {
    return "time_offset must be within +-10 s, got " + std::to_string(config.time_offset);
  }
  if (!std::isfinite(config.readout_time) || config.readout_time < 0.0 || config.readout_time > 1.0) {
    return "readout_time must be between 0 and 1 s, got " + std::to_string(config.readout_time);
  }
  PatchTimeReference patch_time;
  if (config.patch_time == "centre" || config.patch_time == "center") {
    patch_time = PatchTimeReference::kPatchCentre;
  } else if (config.patch_time == "start") {
    patch_time = PatchTimeReference::kPatchStart;
  } else {
    return "patch_time must be 'centre' or 'start', got '" + config.patch_time + "'";
  }
  if (!std::isfinite(config.color_max_flow) || config.color_max_flow < 0.0) {
    return "color_max_flow must be >= 0 pixels, got " + std::to_string(config.color_max_flow);
  }
  if (!std::isfinite(config.imu_wait_timeout) || config.imu_wait_timeout <= 0.0) {
    return "imu_wait_timeout must be a positive number of seconds, got " +
           std::to_string(config.imu_wait_timeout);
  }
  const Eigen::Vector3d bias(config.gyro_bias_x, config.gyro_bias_y, config.gyro_bias_z);
  if (!bias.allFinite() || bias.cwiseAbs().maxCoeff() > 1.0) {
    return "gyro_bias_x/y/z must be within +-1 rad/s";
  }
  Eigen::Matrix3d rotation = params.rolling_shutter.imu_to_camera_rotation;
  const bool from_tf = config.r_cam_imu.find_first_not_of(" \t") == std::string::npos;
  if (!from_tf) {
    const std::string problem = parseRotation(config.r_cam_imu, rotation);
    if (!problem.empty()) return problem;
  }
  params.rolling_shutter.time_offset_s = config.time_offset;
  params.integration.gyro_bias_rad_s = bias;
  params.rotation_from_tf = from_tf;
  params.rolling_shutter.imu_to_camera_rotation = rotation;
  params.rolling_shutter.readout_time_s = config.readout_time;
  params.rolling_shutter.patch_time = patch_time;
  params.color_max_flow_px = config.color_max_flow;
  params.imu_wait_timeout_s = config.imu_wait_timeout;
  return "";
}

GyroFlowConfig toGyroFlowConfig(const GyroFlowParameters& params) {
  GyroFlowConfig config = GyroFlowConfig::__getDefault__();
  config.time_offset = params.rolling_shutter.time_offset_s;
  config.readout_time = params.rolling_shutter.readout_time_s;
  config.patch_time =
      params.rolling_shutter.patch_time == PatchTimeReference::kPatchStart ? "start" : "centre";
  config.color_max_flow = params.color_max_flow_px;
  config.imu_wait_timeout = params.imu_wait_timeout_s;
  config.gyro_bias_x = params.integration.gyro_bias_rad_s.x();
  config.gyro_bias_y = params.integration.gyro_bias_rad_s.y();
  config.gyro_bias_z = params.integration.gyro_bias_rad_s.z();
  config.r_cam_imu.clear();
  if (!params.rotation_from_tf) {
    std::ostringstream out;
    out.precision(12);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) out << (r || c ? " " : "") << params.rolling_shutter.imu_to_camera_rotation(r, c);
    config.r_cam_imu = out.str();
  }
  return config;
}

void applyOnlineCalibration(const OnlineCalibration& msg, GyroFlowParameters& params) {
  params.rolling_shutter.time_offset_s = msg.time_offset;
  params.time_offset_rate = msg.time_offset_rate;
  params.time_offset_reference_s = msg.time_offset_reference.toSec();
  params.rolling_shutter.readout_time_s = msg.readout_time;
  params.integration.gyro_bias_rad_s = Eigen::Vector3d(msg.gyro_bias[0], msg.gyro_bias[1], msg.gyro_bias[2]);
  if (msg.mount_estimated) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        params.rolling_shutter.imu_to_camera_rotation(r, c) = msg.imu_to_camera_rotation[static_cast<std::size_t>(3 * r + c)];
    params.rotation_from_tf = false;
  }
}

GyroFlowReconfigure::GyroFlowReconfigure(const ros::NodeHandle& private_nh, const std::string& log_name,
                                         const GyroFlowParameters& loaded, Apply apply)
    : log_name_(log_name), current_(loaded), apply_(std::move(apply)), server_(server_mutex_, private_nh) {
  GyroFlowConfig initial = toGyroFlowConfig(loaded);
  server_.updateConfig(initial);
  server_.setCallback([this](GyroFlowConfig& config, uint32_t level) { callback(config, level); });
}

void GyroFlowReconfigure::callback(GyroFlowConfig& config, uint32_t) {
  GyroFlowParameters updated = current_;
  const std::string problem = applyGyroFlowConfig(config, updated);
  if (!problem.empty()) {
    ROS_WARN_NAMED(log_name_, "%s: reconfigure refused: %s; keeping the previous values",
                   log_name_.c_str(), problem.c_str());
    config = toGyroFlowConfig(current_);
    return;
  }
  const RollingShutterConfig& a = updated.rolling_shutter;
  const RollingShutterConfig& b = current_.rolling_shutter;
  // An offset set by hand is constant: the online calibration's drift goes with the offset it came with.
  if (a.time_offset_s != b.time_offset_s) updated.time_offset_rate = updated.time_offset_reference_s = 0.0;
  const bool changed = a.time_offset_s != b.time_offset_s || a.readout_time_s != b.readout_time_s ||
                       a.patch_time != b.patch_time || updated.color_max_flow_px != current_.color_max_flow_px ||
                       updated.imu_wait_timeout_s != current_.imu_wait_timeout_s ||
                       updated.integration.gyro_bias_rad_s != current_.integration.gyro_bias_rad_s ||
                       updated.rotation_from_tf != current_.rotation_from_tf ||
                       updated.rolling_shutter.imu_to_camera_rotation != current_.rolling_shutter.imu_to_camera_rotation;
  current_ = updated;
  if (changed) {
    ROS_INFO_NAMED(log_name_,
                   "%s: reconfigured: time offset %.4f s, readout %.4f s, patch time %s, color max flow "
                   "%.2f px, IMU wait timeout %.3f s, gyro bias (%.5f, %.5f, %.5f) rad/s, R_cam_imu %s (from "
                   "the next frame pair)",
                   log_name_.c_str(), config.time_offset, config.readout_time, config.patch_time.c_str(),
                   config.color_max_flow, config.imu_wait_timeout, config.gyro_bias_x, config.gyro_bias_y,
                   config.gyro_bias_z, config.r_cam_imu.empty() ? "from tf"
                                                                            : config.r_cam_imu.c_str());
  }
  apply_(current_);
}

std::string GyroFlowReconfigure::set(const GyroFlowParameters& wanted) {
  // The server holds this lock around its own callback: a client's change and this one do not interleave.
  boost::recursive_mutex::scoped_lock lock(server_mutex_);
  GyroFlowConfig config = toGyroFlowConfig(wanted);
  GyroFlowParameters updated = current_;
  const std::string problem = applyGyroFlowConfig(config, updated);
  if (!problem.empty()) return problem;
  // Not a reconfigure parameter: the online calibration's drift comes with its offset.
  updated.time_offset_rate = wanted.time_offset_rate;
  updated.time_offset_reference_s = wanted.time_offset_reference_s;
  current_ = updated;
  server_.updateConfig(config);  // published on ~parameter_updates: dynparam get shows it
  apply_(current_);
  return "";
}

}  // namespace deep_ois
