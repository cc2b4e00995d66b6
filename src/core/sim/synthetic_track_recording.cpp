#include "deep_ois/core/sim/synthetic_track_recording.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/sim_camera.h"

namespace deep_ois {
namespace sim {

SyntheticTrackRecording makeSyntheticTrackRecording(const SimulatorConfig& config,
                                                    const SyntheticTrackOptions& options) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("synthetic tracks: " + problem);
  if (!(options.duration_s > 0.1) || options.tracks_per_pair < 1 || !(options.track_noise_px >= 0.0) ||
      !(options.outlier_fraction >= 0.0 && options.outlier_fraction < 1.0) ||
      !(options.near_m > 0.0 && options.far_m >= options.near_m)) {
    throw std::invalid_argument(
        "synthetic tracks: needs duration_s > 0.1, tracks_per_pair >= 1, track_noise_px >= 0, outlier_fraction in "
        "[0, 1) and 0 < near_m <= far_m");
  }
  const SensorConfig& sensor = config.sensor;
  const double start_s = -0.5, end_s = options.duration_s + 0.5;
  const CameraMotion motion(config.motion, options.seed, start_s, end_s);
  const CameraModel nominal = nominalCamera(sensor);
  const OisModel ois(config.ois, motion, nominal.K()(0, 0), options.seed);
  OisConfig no_ois_config = config.ois;
  no_ois_config.enabled = false;
  const OisModel no_ois(no_ois_config, motion, nominal.K()(0, 0), options.seed);
  const SimCamera camera(sensor, motion, ois);
  const SimCamera camera_without_lens(sensor, motion, no_ois);

  SyntheticTrackRecording out;
  out.camera = nominal;
  out.readout_time_s = sensor.readout_time_s;
  out.imu_to_camera_rotation = config.imu.imu_to_camera_rotation;
  const double base_offset_s = config.imu.time_offset_s;
  const std::function<double(double)> extra = options.extra_offset_s;
  out.time_offset_s = [base_offset_s, extra](double t) { return base_offset_s + (extra ? extra(t) : 0.0); };

  const std::vector<ImuMeasurement> imu = sampleImu(config.imu, motion, options.seed, -0.4, options.duration_s + 0.4);
  Eigen::Vector3d bias_sum = Eigen::Vector3d::Zero();
  for (const ImuMeasurement& m : imu) {
    // The IMU stamp of camera time t is t + offset(t); the simulator gave t + base offset.
    const double t_camera = m.stamp_s - base_offset_s;
    const double stamp_s = m.stamp_s + (extra ? extra(t_camera) : 0.0);
    if (!out.gyro.empty() && stamp_s <= out.gyro.back().stamp_s) continue;  // a backward jump overlaps
    out.gyro.push_back({stamp_s, m.angular_velocity_rad_s});
    bias_sum += m.true_bias_rad_s;
  }
  if (!imu.empty()) out.mean_bias_rad_s = bias_sum / static_cast<double>(imu.size());

  std::mt19937 rng(options.seed * 7919u + 17u);
  std::uniform_real_distribution<double> u(8.0, sensor.width_px - 9.0), v(8.0, sensor.height_px - 9.0);
  std::uniform_real_distribution<double> inverse_depth(1.0 / options.far_m, 1.0 / options.near_m);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, options.track_noise_px);
  const int frames = static_cast<int>(options.duration_s * sensor.frame_rate_hz) + 1;
  for (int k = 0; k + 1 < frames; ++k) {
    SyntheticTrackPair pair;
    pair.stamp_a_s = k / sensor.frame_rate_hz;
    pair.stamp_b_s = (k + 1) / sensor.frame_rate_hz;
    for (int attempt = 0; attempt < 4 * options.tracks_per_pair &&
                          static_cast<int>(pair.matches.size()) < options.tracks_per_pair;
         ++attempt) {
      const Eigen::Vector2d pixel_a(u(rng), v(rng));
      const double depth_m = 1.0 / inverse_depth(rng);
      const double t_a = camera.rowTime(pair.stamp_a_s, pixel_a.y());
      const Eigen::Vector3d X = motion.pose(t_a).centre_world_m + depth_m * camera.rayDirectionWorld(pixel_a, t_a);
      Eigen::Vector2d pixel_b, plain_a, plain_b;
      if (!camera.projectRollingShutter(X, pair.stamp_b_s, &pixel_b)) continue;
      if (!camera_without_lens.projectRollingShutter(X, pair.stamp_a_s, &plain_a) ||
          !camera_without_lens.projectRollingShutter(X, pair.stamp_b_s, &plain_b)) {
        continue;
      }
      Eigen::Vector2d error_a(noise(rng), noise(rng)), error_b(noise(rng), noise(rng));
      if (unit(rng) < options.outlier_fraction) {
        const double angle = 2.0 * 3.14159265358979323846 * unit(rng);
        error_b += (3.0 + 7.0 * unit(rng)) * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      }
      auto match = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        FeatureMatch m;
        m.point_a_px = cv::Point2f(static_cast<float>(a.x()), static_cast<float>(a.y()));
        m.point_b_px = cv::Point2f(static_cast<float>(b.x()), static_cast<float>(b.y()));
        return m;
      };
      pair.matches.push_back(match(pixel_a + error_a, pixel_b + error_b));
      pair.matches_without_lens.push_back(match(plain_a + error_a, plain_b + error_b));
    }
    out.pairs.push_back(std::move(pair));
  }
  return out;
}

}  // namespace sim
}  // namespace deep_ois
