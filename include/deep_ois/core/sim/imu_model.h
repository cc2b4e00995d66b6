// A phone MEMS gyroscope (and accelerometer) sampling the simulated motion.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/sim/camera_motion.h"

namespace deep_ois {
namespace sim {

struct ImuConfig {
  double rate_hz = 400.0;
  // R_cam_imu: a vector in the IMU frame is R * v in the camera optical frame. Default: a phone
  // mount (IMU x = camera y, IMU y = camera x, IMU z = -camera z); a proper rotation.
  Eigen::Matrix3d imu_to_camera_rotation = (Eigen::Matrix3d() << 0, 1, 0, 1, 0, 0, 0, 0, -1).finished();
  // Gyro white noise density, rad/s/sqrt(Hz) (per-sample sigma = density * sqrt(rate / 2)).
  double gyro_noise_density = 1.0e-4;
  // Gyro bias random walk, rad/s^2/sqrt(Hz); the bias starts at a random value of this spread.
  double gyro_bias_random_walk = 2.0e-5;
  double gyro_initial_bias_rad_s = 0.002;
  // When set, the bias at the first sample instead of the random draw (IMU frame, rad/s): a known
  // bias for calibration tests. The random draw is still made, so the other streams are unchanged.
  std::optional<Eigen::Vector3d> gyro_initial_bias_vector_rad_s;
  double accel_noise_density = 2.0e-3;  // m/s^2/sqrt(Hz)
  // IMU clock = camera clock + time_offset_s (the simulated clock offset).
  double time_offset_s = 0.0;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

struct ImuMeasurement {
  double stamp_s;                          // IMU clock
  Eigen::Vector3d angular_velocity_rad_s;  // IMU frame, with noise and bias
  Eigen::Vector3d linear_acceleration_m_s2;  // IMU frame, specific force (gravity included)
  Eigen::Vector3d true_bias_rad_s;         // the bias inside angular_velocity_rad_s
};

// Samples [start_s, end_s] of camera-clock time at rate_hz (stamps on the IMU clock).
std::vector<ImuMeasurement> sampleImu(const ImuConfig& config, const CameraMotion& motion,
                                      std::uint32_t seed, double start_s, double end_s);

}  // namespace sim
}  // namespace deep_ois
