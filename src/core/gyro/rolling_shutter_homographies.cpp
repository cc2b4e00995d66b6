#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <sstream>

namespace deep_ois {

std::string RollingShutterConfig::validate() const {
  std::ostringstream why;
  if (patch_count < 1) {
    why << "patch_count must be at least 1 (got " << patch_count << ")";
  } else if (!std::isfinite(readout_time_s) || readout_time_s < 0.0) {
    why << "readout_time must be a non-negative number of seconds (got " << readout_time_s << ")";
  } else if (!std::isfinite(time_offset_s)) {
    why << "time_offset must be finite (got " << time_offset_s << ")";
  } else if (!isProperRotation(imu_to_camera_rotation)) {
    why << "imu_to_camera_rotation must be a proper rotation matrix (orthonormal, det +1)";
  }
  return why.str();
}

double patchImuTime(const RollingShutterConfig& config, double frame_stamp_s, int patch_index) {
  const double row_fraction = config.patch_time == PatchTimeReference::kPatchCentre
                                  ? (patch_index + 0.5) / config.patch_count
                                  : static_cast<double>(patch_index) / config.patch_count;
  return frame_stamp_s + config.time_offset_s + config.readout_time_s * row_fraction;
}

ImuInterval requiredImuInterval(const RollingShutterConfig& config, double stamp_a_s,
                                double stamp_b_s) {
  return {patchImuTime(config, stamp_a_s, 0),
          patchImuTime(config, stamp_b_s, config.patch_count - 1)};
}

int patchIndexOfRow(double row_px, int image_height_px, int patch_count) {
  // Row r covers [r - 0.5, r + 0.5); patch i holds integer rows [i*h/N, (i+1)*h/N).
  const double index = std::floor((std::floor(row_px + 0.5) * patch_count) / image_height_px);
  return static_cast<int>(std::clamp(index, 0.0, static_cast<double>(patch_count - 1)));
}

Eigen::Matrix3d rotationHomography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& R_b_a) {
  Eigen::Matrix3d H = K * R_b_a * K.inverse();
  return H / H(2, 2);
}

RollingShutterHomographies computeRollingShutterHomographies(const ImuSampleBuffer& buffer,
                                                             const IntegrationOptions& integration,
                                                             const RollingShutterConfig& config,
                                                             const Eigen::Matrix3d& K,
                                                             double stamp_a_s, double stamp_b_s) {
  RollingShutterHomographies result;
  const Eigen::Matrix3d& R_cam_imu = config.imu_to_camera_rotation;
  const Eigen::Matrix3d K_inv = K.inverse();
  const double frame_interval_s = stamp_b_s - stamp_a_s;
  result.homographies.reserve(config.patch_count);
  result.rotations.reserve(config.patch_count);
  for (int i = 0; i < config.patch_count; ++i) {
    const double t_a = patchImuTime(config, stamp_a_s, i);
    const IntegrationResult delta = integrateRotation(buffer, t_a, t_a + frame_interval_s, integration);
    if (!delta.ok()) {
      result.status = delta.status;
      result.reason = delta.reason;
      result.homographies.clear();
      result.rotations.clear();
      return result;
    }
    // delta.rotation = R_imu(t_a)^T R_imu(t_b); in the camera frame it is conjugated by R_cam_imu,
    // and a static point moves by its transpose: X_b = R_b_a X_a.
    const Eigen::Matrix3d R_b_a = R_cam_imu * delta.rotation.transpose() * R_cam_imu.transpose();
    Eigen::Matrix3d H = K * R_b_a * K_inv;
    result.homographies.push_back(H / H(2, 2));
    result.rotations.push_back(R_b_a);
  }
  return result;
}

}  // namespace deep_ois
