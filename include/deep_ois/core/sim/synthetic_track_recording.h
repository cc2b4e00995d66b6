// A simulated recording as point tracks, without rendering: the simulator's camera motion, OIS
// lens and IMU give the gyro stream and, per frame pair, tracks of static world points projected
// through the rolling shutter with their own row times (SimCamera::projectRollingShutter), with
// tracker noise and a share of outliers (moving objects, mismatches). The camera-IMU time offset
// may change along the recording (a drift, a jump), which the simulator's IMU cannot do: the IMU
// stamps are moved by the extra offset at each sample's time. For the online calibration's tests
// and benchmark: thousands of pairs in a second, with the truth known at every moment.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {
namespace sim {

struct SyntheticTrackOptions {
  double duration_s = 30.0;
  std::uint32_t seed = 1;
  int tracks_per_pair = 80;
  double track_noise_px = 0.1;    // per coordinate, Gaussian
  double outlier_fraction = 0.05;  // tracks moved by 3-10 px in a random direction
  double near_m = 3.0, far_m = 30.0;  // depth range of the tracked points (parallax under translation)
  // Extra camera-IMU offset at camera time t (seconds), added to the configuration's
  // imu.time_offset_s; empty = none.
  std::function<double(double)> extra_offset_s;
};

struct SyntheticTrackPair {
  double stamp_a_s = 0.0, stamp_b_s = 0.0;  // camera clock
  std::vector<FeatureMatch> matches;        // raw pixels; lens shift included when OIS is on
  // The same world points without the lens shift (an oracle stabiliser model): what the plain
  // gyro must explain once the lens motion is compensated. Same order, same noise.
  std::vector<FeatureMatch> matches_without_lens;
};

struct SyntheticTrackRecording {
  CameraModel camera;
  std::vector<ImuSample> gyro;  // IMU frame, IMU clock
  std::vector<SyntheticTrackPair> pairs;
  double readout_time_s = 0.0;
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d mean_bias_rad_s = Eigen::Vector3d::Zero();  // the IMU's bias over the recording
  std::function<double(double)> time_offset_s;  // the true offset at camera time t
};

// Throws std::invalid_argument for an invalid configuration or options.
SyntheticTrackRecording makeSyntheticTrackRecording(const SimulatorConfig& config, const SyntheticTrackOptions& options);

}  // namespace sim
}  // namespace deep_ois
