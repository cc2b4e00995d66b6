#include "deep_ois/core/calibration/calibration_yaml.h"

#include <Eigen/Geometry>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

std::string list(const double* values, int count) {
  std::ostringstream out;
  out << std::setprecision(15) << "[";
  for (int i = 0; i < count; ++i) out << (i ? ", " : "") << values[i];
  out << "]";
  return out.str();
}

}  // namespace

std::string staticTransformCommand(const Eigen::Matrix3d& imu_to_camera_rotation,
                                   const std::string& imu_frame_id, const std::string& camera_frame_id) {
  const Eigen::Quaterniond q(Eigen::Matrix3d(imu_to_camera_rotation.transpose()));
  std::ostringstream out;
  out << std::fixed << std::setprecision(9) << "rosrun tf2_ros static_transform_publisher 0 0 0 " << q.x() << " "
      << q.y() << " " << q.z() << " " << q.w() << " " << (imu_frame_id.empty() ? "imu_link" : imu_frame_id) << " "
      << (camera_frame_id.empty() ? "camera_optical_frame" : camera_frame_id);
  return out.str();
}

std::string calibrationYaml(const CalibrationResult& result, const CalibrationProvenance& provenance) {
  const CameraImuCalibration& c = result.calibration;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> rotation = c.imu_to_camera_rotation;
  std::ostringstream out;
  out << "# Camera-IMU calibration by deep_ois calibrate, from " << provenance.source << "\n"
      << "# Parameters of the deep_ois/gyro_flow nodelet: load this file after config/gyro_flow.yaml\n"
      << "#   roslaunch deep_ois gyro_flow.launch calibration:=<this file>\n";
  out << std::fixed << std::setprecision(3) << "# " << result.pairs_used << " frame pairs, " << result.tracks_used
      << " tracks, median residual " << result.median_residual_px << " px (coarse stage "
      << result.initial_median_residual_px << " px), lens shift handling: " << toString(provenance.lens_shift)
      << "\n";
  out << "# 1-sigma: time offset " << c.time_offset_sigma_s * 1e3 << " ms, readout " << c.readout_time_sigma_s * 1e3
      << " ms, rotation (" << c.rotation_sigma_rad(0) * kRadToDeg << ", " << c.rotation_sigma_rad(1) * kRadToDeg
      << ", " << c.rotation_sigma_rad(2) * kRadToDeg << ") deg about camera x, y, z, bias " << std::scientific
      << std::setprecision(1) << c.gyro_bias_sigma_rad_s.maxCoeff() << " rad/s\n";
  for (const std::string& note : provenance.notes) out << "# " << note << "\n";
  if (!result.ok()) out << "# REFUSED (do not use): " << result.reason() << "\n";
  out << std::setprecision(15) << std::defaultfloat;
  out << "# Seconds from the start of readout of the first row to that of the last row.\n"
      << "readout_time: " << c.readout_time_s << "\n"
      << "# Seconds added to camera stamps to get IMU time.\n"
      << "time_offset: " << c.time_offset_s << "\n"
      << "# R_cam_imu, row-major (replaces the tf lookup).\n"
      << "imu_to_camera_rotation: " << list(rotation.data(), 9) << "\n"
      << "# Constant gyro bias subtracted from every sample, rad/s, IMU frame.\n"
      << "gyro_bias: " << list(c.gyro_bias_rad_s.data(), 3) << "\n"
      << "# The same rotation as a static transform (the time offset has no tf equivalent):\n"
      << "#   " << staticTransformCommand(c.imu_to_camera_rotation, provenance.imu_frame_id, provenance.camera_frame_id)
      << "\n";
  return out.str();
}

void writeTextFile(const std::string& path, const std::string& text) {
  const std::string temporary = path + ".tmp";
  {
    std::ofstream file(temporary, std::ios::trunc);
    if (!file) throw std::runtime_error(path + ": cannot open for writing");
    file << text;
    file.flush();
    if (!file) throw std::runtime_error(path + ": writing failed");
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    std::remove(temporary.c_str());
    throw std::runtime_error(path + ": cannot move the written file into place");
  }
}

}  // namespace deep_ois
