#include "deep_ois/core/sim/imu_model.h"

#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kGravityM_s2 = 9.81;

}  // namespace

std::string ImuConfig::validate() const {
  std::ostringstream why;
  auto nonNegative = [](double x) { return std::isfinite(x) && x >= 0.0; };
  const Eigen::Matrix3d& R = imu_to_camera_rotation;
  if (!std::isfinite(rate_hz) || !(rate_hz > 0.0)) {
    why << "rate_hz: must be positive (got " << rate_hz << " Hz)";
  } else if (!isProperRotation(R)) {
    why << "imu_to_camera_rotation: must be a proper rotation matrix (orthonormal, det +1)";
  } else if (!nonNegative(gyro_noise_density)) {
    why << "gyro_noise_density: must be non-negative (got " << gyro_noise_density << ")";
  } else if (!nonNegative(gyro_bias_random_walk)) {
    why << "gyro_bias_random_walk: must be non-negative (got " << gyro_bias_random_walk << ")";
  } else if (!nonNegative(gyro_initial_bias_rad_s)) {
    why << "gyro_initial_bias_rad_s: must be non-negative (got " << gyro_initial_bias_rad_s << ")";
  } else if (gyro_initial_bias_vector_rad_s && !gyro_initial_bias_vector_rad_s->allFinite()) {
    why << "gyro_initial_bias_vector_rad_s: must hold finite numbers";
  } else if (!nonNegative(accel_noise_density)) {
    why << "accel_noise_density: must be non-negative (got " << accel_noise_density << ")";
  } else if (!std::isfinite(time_offset_s) || std::abs(time_offset_s) > 1.0) {
    why << "time_offset_s: must be within +-1 s (got " << time_offset_s << " s)";
  }
  return why.str();
}

// The IMU samples on its own clock: stamps are the integer multiples of 1 / rate_hz (IMU clock)
// whose camera-clock time, stamp - time_offset_s, lies in [start_s, end_s]; the motion is
// evaluated at that camera time. So a time offset shifts the sample instants against the camera
// frames by a fraction of a period, as with a real free-running IMU.
std::vector<ImuMeasurement> sampleImu(const ImuConfig& config, const CameraMotion& motion,
                                      std::uint32_t seed, double start_s, double end_s) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("imu: " + problem);
  if (!std::isfinite(start_s) || !std::isfinite(end_s) || end_s < start_s) {
    std::ostringstream why;
    why << "imu: the time span must be finite with end >= start (got [" << start_s << ", " << end_s
        << "] s)";
    throw std::invalid_argument(why.str());
  }
  const double dt = 1.0 / config.rate_hz;
  // The tolerance keeps a span edge that is itself a tick (up to rounding) inside.
  const double first = std::ceil((start_s + config.time_offset_s) * config.rate_hz - 1e-6);
  const double last = std::floor((end_s + config.time_offset_s) * config.rate_hz + 1e-6);

  // Continuous-time densities to per-sample sigmas: white noise band-limited to Nyquist, the
  // bias a random walk advancing once per sample.
  const double gyro_sigma = config.gyro_noise_density * std::sqrt(config.rate_hz / 2.0);
  const double accel_sigma = config.accel_noise_density * std::sqrt(config.rate_hz / 2.0);
  const double bias_step_sigma = config.gyro_bias_random_walk * std::sqrt(dt);

  std::mt19937 gyro_rng = streamGenerator(seed, 0);
  std::mt19937 bias_rng = streamGenerator(seed, 1);
  std::mt19937 accel_rng = streamGenerator(seed, 2);
  Eigen::Vector3d bias = config.gyro_initial_bias_rad_s * gaussian3(bias_rng);
  if (config.gyro_initial_bias_vector_rad_s) bias = *config.gyro_initial_bias_vector_rad_s;

  const Eigen::Matrix3d R_imu_cam = config.imu_to_camera_rotation.transpose();
  const Eigen::Vector3d gravity_world(0.0, 0.0, -kGravityM_s2);
  std::vector<ImuMeasurement> samples;
  if (last >= first) samples.reserve(static_cast<std::size_t>(last - first) + 1);
  for (double tick = first; tick <= last; tick += 1.0) {
    ImuMeasurement m;
    m.stamp_s = tick / config.rate_hz;
    const double t_cam = m.stamp_s - config.time_offset_s;
    m.true_bias_rad_s = bias;
    m.angular_velocity_rad_s =
        R_imu_cam * motion.angularVelocity(t_cam) + bias + gyro_sigma * gaussian3(gyro_rng);
    // Specific force: what an accelerometer reads is acceleration minus gravity, in its frame.
    const Eigen::Matrix3d R_world_cam = motion.pose(t_cam).R_world_cam;
    m.linear_acceleration_m_s2 =
        R_imu_cam * (R_world_cam.transpose() * (motion.linearAcceleration(t_cam) - gravity_world)) +
        accel_sigma * gaussian3(accel_rng);
    samples.push_back(m);
    bias += bias_step_sigma * gaussian3(bias_rng);
  }
  return samples;
}

}  // namespace sim
}  // namespace deep_ois
