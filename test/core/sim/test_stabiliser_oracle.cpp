// The stabiliser oracle (core/sim/stabiliser_oracle.h) is the simulator's own stabiliser on another
// gyro: fed the stabiliser's own gyro it must give the simulator's lens truth, fed the camera's
// IMU (another noise, bias and rate) it stays close to it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/sim_camera.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/core/sim/stabiliser_oracle.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDurationS = 3.0;

SimulatorConfig design(const std::string& module) {
  const std::string dir = std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/";
  if (module.empty()) return loadSimulatorConfig(dir + "RE.yaml");
  return loadSimulatorConfig(dir + "RE.yaml", {dir + "modules/" + module + ".yaml"});
}

// The designs of every controller, loop and mount the simulator has.
const char* const kModules[] = {"",  // the package's camera: high-pass, second-order actuator
                                "intended_motion_kalman", "excursion_soft_stroke", "digital_loop",
                                "rotated_mount", "pi_position_loop", "pan_release",
                                "hall_noisy_circular"};

// The stabiliser's own gyro as OisModel measures it (the true rate turned by the mount, plus its
// white noise drawn from the OisModel's seed in the same order), turned back into the camera
// frame: what the oracle is fed to be the simulator's stabiliser itself.
std::vector<CameraRateSample> stabiliserGyro(const OisConfig& ois, const CameraMotion& motion,
                                             std::uint32_t seed) {
  std::mt19937 rng(seed);
  const double dt = 1.0 / ois.control_rate_hz;
  const int steps = static_cast<int>(
      std::ceil((motion.endTime() - motion.startTime()) * ois.control_rate_hz));
  const double mount = ois.mount_rotation_deg * kPi / 180.0;
  Eigen::Matrix2d to_gyro;
  to_gyro << std::cos(mount), std::sin(mount), -std::sin(mount), std::cos(mount);
  std::vector<CameraRateSample> rates;
  for (int j = 0; j <= steps; ++j) {
    const double t = motion.startTime() + j * dt;
    const Eigen::Vector3d w = motion.angularVelocity(t);
    const double noise_x = ois.gyro_noise_rad_s * gaussian(rng);
    const double noise_y = ois.gyro_noise_rad_s * gaussian(rng);
    const Eigen::Vector2d measured = to_gyro * w.head<2>() + Eigen::Vector2d(noise_x, noise_y);
    rates.push_back({t, Eigen::Vector3d(0.0, 0.0, w.z())});
    rates.back().rate_rad_s.head<2>() = to_gyro.transpose() * measured;
  }
  return rates;
}

TEST(StabiliserOracle, OnTheStabilisersOwnGyroItIsTheSimulatorsLens) {
  for (const char* module : kModules) {
    SCOPED_TRACE(std::string("module '") + module + "'");
    OisConfig ois = design(module).ois;
    // The Hall sensor's noise is not the gyro's: the oracle leaves it out (its mean).
    ois.hall_noise_px = 0.0;
    const CameraMotionConfig motion_config = design(module).motion;
    const CameraMotion motion(motion_config, 11, -0.25, kDurationS);
    const double focal_px = nominalCamera(design(module).sensor).K()(0, 0);
    const OisModel truth(ois, motion, focal_px, 12);
    const StabiliserOracle oracle(ois, focal_px, stabiliserGyro(ois, motion, 12));
    double largest = 0.0, motion_px = 0.0;
    for (double t = motion.startTime(); t < kDurationS - 0.01; t += 0.00123) {
      largest = std::max(largest, (oracle.lensShift(t) - truth.lensShift(t)).norm());
      motion_px = std::max(motion_px, truth.lensShift(t).norm());
    }
    EXPECT_GT(motion_px, 0.5);  // the lens moves
    EXPECT_LT(largest, 1e-6 * motion_px);
    EXPECT_EQ(0, oracle.droppedSamples());
  }
}

TEST(StabiliserOracle, OnTheCamerasImuItStaysCloseToTheSimulatorsLens) {
  for (const char* module : {"", "intended_motion_kalman", "rotated_mount"}) {
    SCOPED_TRACE(std::string("module '") + module + "'");
    const SimulatorConfig config = design(module);
    const CameraMotion motion(config.motion, 21, -0.25, kDurationS);
    const double focal_px = nominalCamera(config.sensor).K()(0, 0);
    const OisModel truth(config.ois, motion, focal_px, 22);
    // The camera's IMU (400 Hz, its own noise and bias, on its own mount), into the camera frame.
    std::vector<CameraRateSample> rates;
    for (const ImuMeasurement& m : sampleImu(config.imu, motion, 23, -0.25, kDurationS)) {
      rates.push_back({m.stamp_s, config.imu.imu_to_camera_rotation * m.angular_velocity_rad_s});
    }
    const StabiliserOracle oracle(config.ois, focal_px, rates);
    // Frame-to-frame lens motion (30 Hz), the part of the lens a frame pair's alignment sees.
    double error = 0.0, lens = 0.0;
    int n = 0;
    for (double t = 0.5; t + 1.0 / 30.0 < kDurationS - 0.1; t += 0.01, ++n) {
      const Eigen::Vector2d true_motion = truth.lensShift(t + 1.0 / 30.0) - truth.lensShift(t);
      const Eigen::Vector2d oracle_motion = oracle.lensShift(t + 1.0 / 30.0) - oracle.lensShift(t);
      error += (oracle_motion - true_motion).squaredNorm();
      lens += true_motion.squaredNorm();
    }
    std::printf("[ figures  ] %s: frame-to-frame lens motion %.3f px RMS, oracle error %.4f px RMS\n",
                module[0] ? module : "RE", std::sqrt(lens / n), std::sqrt(error / n));
    // Not exact (another gyro), but within a tenth of the lens motion; a wrong frame or sign
    // would be as large as the motion itself.
    EXPECT_LT(std::sqrt(error / n), 0.1 * std::sqrt(lens / n));
  }
}

TEST(StabiliserOracle, StartsWhenToldWithTheFirstSampleHeldBackToIt) {
  const SimulatorConfig config = design("intended_motion_kalman");
  const CameraMotion motion(config.motion, 31, 0.0, 1.5);
  std::vector<CameraRateSample> rates;
  for (double t = 0.0; t < 1.5; t += 0.0025) rates.push_back({t, motion.angularVelocity(t)});
  const double focal_px = nominalCamera(config.sensor).K()(0, 0);
  // Started 0.15 s early: as if the gyro had a sample then with the first sample's rate.
  const StabiliserOracle early(config.ois, focal_px, rates, -0.15);
  std::vector<CameraRateSample> held = rates;
  held.insert(held.begin(), {-0.15, rates.front().rate_rad_s});
  const StabiliserOracle same(config.ois, focal_px, held);
  const StabiliserOracle late(config.ois, focal_px, rates);
  EXPECT_TRUE(early.covers(-0.1));
  EXPECT_FALSE(late.covers(-0.1));
  double largest = 0.0, start_effect = 0.0;
  for (double t = 0.0; t < 1.4; t += 0.01) {
    largest = std::max(largest, (early.lensShift(t) - same.lensShift(t)).norm());
    start_effect = std::max(start_effect, (early.lensShift(t) - late.lensShift(t)).norm());
  }
  EXPECT_LT(largest, 1e-9);
  EXPECT_GT(start_effect, 0.01);  // the start matters to a slow estimator
  EXPECT_THROW(StabiliserOracle(config.ois, focal_px, rates, 2.0), std::invalid_argument);
}

TEST(StabiliserOracle, RefusesWhatItCannotRunAndCountsDroppedSamples) {
  OisConfig ois;
  std::vector<CameraRateSample> rates = {{0.0, Eigen::Vector3d::Zero()},
                                         {0.01, Eigen::Vector3d(0.1, 0.0, 0.0)},
                                         {0.01, Eigen::Vector3d::Zero()},   // repeated
                                         {0.005, Eigen::Vector3d::Zero()},  // back in time
                                         {0.02, Eigen::Vector3d(0.1, 0.0, 0.0)}};
  const StabiliserOracle oracle(ois, 257.0, rates);
  EXPECT_EQ(2, oracle.droppedSamples());
  EXPECT_TRUE(oracle.covers(0.015));
  EXPECT_FALSE(oracle.covers(0.021));
  EXPECT_THROW(StabiliserOracle(ois, 257.0, {rates.front()}), std::invalid_argument);
  EXPECT_THROW(StabiliserOracle(ois, -1.0, rates), std::invalid_argument);
  OisConfig off = ois;
  off.enabled = false;
  EXPECT_THROW(StabiliserOracle(off, 257.0, rates), std::invalid_argument);
  OisConfig bad = ois;
  bad.gain = 5.0;
  try {
    StabiliserOracle(bad, 257.0, rates);
    FAIL() << "an invalid design was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string::npos, std::string(e.what()).find("gain"));
  }
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
