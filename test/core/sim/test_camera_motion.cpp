#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/ois_model.h"
#include "test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

CameraMotionConfig shakeOnly() {
  CameraMotionConfig config;
  config.pan_peak_rad_s = 0.0;
  config.translation_rms_m = 0.0;
  return config;
}

// Per-axis RMS of the angular velocity sampled at `rate_hz` over [t0, t1].
Eigen::Vector3d rateRms(const CameraMotion& motion, double t0, double t1, double rate_hz) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const int n = static_cast<int>((t1 - t0) * rate_hz);
  for (int k = 0; k < n; ++k) sum += motion.angularVelocity(t0 + k / rate_hz).cwiseAbs2();
  return (sum / n).cwiseSqrt();
}

TEST(CameraMotion, SameSeedIsBitIdenticalAndSeedsDiffer) {
  const CameraMotionConfig config;
  const CameraMotion a(config, 7, -0.25, 3.0), b(config, 7, -0.25, 3.0), c(config, 8, -0.25, 3.0);
  for (double t : {-0.2, 0.0, 0.4321, 1.7, 2.99}) {
    EXPECT_EQ(a.angularVelocity(t), b.angularVelocity(t));
    EXPECT_EQ(a.linearAcceleration(t), b.linearAcceleration(t));
    EXPECT_EQ(a.pose(t).R_world_cam, b.pose(t).R_world_cam);
    EXPECT_EQ(a.pose(t).centre_world_m, b.pose(t).centre_world_m);
    EXPECT_GT((a.angularVelocity(t) - c.angularVelocity(t)).norm(), 1e-3);
    EXPECT_GT((a.linearAcceleration(t) - c.linearAcceleration(t)).norm(), 1e-4);
  }
}

TEST(CameraMotion, ReferencePoseAtTimeZero) {
  const CameraMotion motion(CameraMotionConfig(), 3, -0.25, 2.0);
  const CameraPose pose = motion.pose(0.0);
  // Optical axis along world +x, camera right along world -y, camera down along world -z.
  EXPECT_MATRIX_NEAR(Eigen::Vector3d(1, 0, 0), pose.R_world_cam.col(2), 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector3d(0, -1, 0), pose.R_world_cam.col(0), 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector3d(0, 0, -1), pose.R_world_cam.col(1), 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector3d::Zero(), pose.centre_world_m, 1e-15);
  // And it moves: a quarter second later the camera has turned and shifted.
  EXPECT_GT(logSO3(pose.R_world_cam.transpose() * motion.pose(0.25).R_world_cam).norm(), 1e-3);
  EXPECT_GT(motion.pose(0.25).centre_world_m.norm(), 1e-4);
}

TEST(CameraMotion, ShakeRmsAndBand) {
  const CameraMotionConfig config = shakeOnly();
  const double duration = 12.0, rate = 200.0;  // Nyquist 100 Hz, far above the 12 Hz band
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const CameraMotion motion(config, seed, 0.0, duration);
    const Eigen::Vector3d rms = rateRms(motion, 0.0, duration, rate);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_NEAR(rms[axis], config.shake_rms_rad_s[axis], 0.15 * config.shake_rms_rad_s[axis])
          << "seed " << seed << " axis " << axis;
    }
    // DFT of each axis (Hann window, 12 s -> 0.083 Hz bins): energy outside the band widened by
    // the window's main lobe, [0.75, 12.25] Hz, against the total.
    const int n = static_cast<int>(duration * rate);
    std::vector<double> cos_table(n), sin_table(n);
    for (int k = 0; k < n; ++k) {
      cos_table[k] = std::cos(2.0 * kPi * k / n);
      sin_table[k] = std::sin(2.0 * kPi * k / n);
    }
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<double> x(n);
      for (int k = 0; k < n; ++k) {
        const double window = 0.5 - 0.5 * std::cos(2.0 * kPi * k / n);
        x[k] = window * motion.angularVelocity(k / rate)[axis];
      }
      double inside = 0.0, outside = 0.0;
      for (int bin = 0; bin <= n / 2; ++bin) {
        double re = 0.0, im = 0.0;
        for (int k = 0; k < n; ++k) {
          const int index = static_cast<int>((static_cast<long>(bin) * k) % n);
          re += x[k] * cos_table[index];
          im -= x[k] * sin_table[index];
        }
        const double frequency = bin * rate / n;
        const bool in_band = frequency >= config.shake_band_low_hz - 0.25 &&
                             frequency <= config.shake_band_high_hz + 0.25;
        (in_band ? inside : outside) += re * re + im * im;
      }
      EXPECT_LT(outside / (inside + outside), 0.01) << "seed " << seed << " axis " << axis;
      if (seed == 1) {
        std::printf(
            "[ figures  ] seed 1 axis %d: rate RMS %.4f rad/s (config %.4f), energy "
            "outside band %.2e\n",
            axis, rms[axis], config.shake_rms_rad_s[axis], outside / (inside + outside));
      }
    }
  }
}

TEST(CameraMotion, RateNeverExceedsPeaks) {
  // Strong shake that would often exceed the peak without the limiter.
  CameraMotionConfig config;
  config.shake_rms_rad_s = Eigen::Vector3d(0.3, 0.3, 0.1);
  config.shake_peak_rad_s = 0.5;
  config.pan_peak_rad_s = 0.2;
  config.pan_period_s = 1.5;
  const CameraMotion motion(config, 11, 0.0, 12.0);
  CameraMotionConfig no_pan = config;
  no_pan.pan_peak_rad_s = 0.0;
  const CameraMotion shake(no_pan, 11, 0.0, 12.0);  // the same shake (its own random stream)
  double max_rate = 0.0, max_shake = 0.0;
  int above_knee = 0;
  const int n = 12 * 4000;
  for (int k = 0; k <= n; ++k) {
    const double t = k / 4000.0;
    max_rate = std::max(max_rate, motion.angularVelocity(t).norm());
    const double s = shake.angularVelocity(t).norm();
    max_shake = std::max(max_shake, s);
    if (s > 0.8 * config.shake_peak_rad_s) ++above_knee;
  }
  EXPECT_LE(max_shake, config.shake_peak_rad_s);
  EXPECT_LE(max_rate, config.shake_peak_rad_s + config.pan_peak_rad_s);
  EXPECT_GT(above_knee, 100);                    // the limiter was exercised
  EXPECT_GT(max_rate, config.shake_peak_rad_s);  // and the pans add to it
}

TEST(CameraMotion, PanRateFollowsItsProfile) {
  CameraMotionConfig config;
  config.shake_rms_rad_s.setZero();
  config.translation_rms_m = 0.0;
  config.pan_peak_rad_s = 0.3;
  config.pan_period_s = 2.0;
  const CameraMotion motion(config, 5, 1.0, 9.0);
  double max_rate = 0.0;
  for (int k = 0; k <= 8000; ++k) {
    const Eigen::Vector3d w = motion.angularVelocity(1.0 + k * 1e-3);
    EXPECT_EQ(0.0, w.z());  // pans are pitch / yaw only
    max_rate = std::max(max_rate, w.norm());
  }
  EXPECT_LE(max_rate, config.pan_peak_rad_s);
  EXPECT_GE(max_rate, 0.3 * config.pan_peak_rad_s);
  // Each pan starts and ends at rest, at start + k * period.
  for (int k = 0; k <= 4; ++k) {
    EXPECT_LT(motion.angularVelocity(1.0 + 2.0 * k).norm(), 1e-12);
  }
}

// The integrator on a gyro of exact samples of angularVelocity() must give pose()'s rotation.
TEST(CameraMotion, PoseAgreesWithIntegratedRate) {
  CameraMotionConfig config;  // shake, pans and the limiter all in play
  config.shake_rms_rad_s = Eigen::Vector3d(0.25, 0.25, 0.1);
  const double start = -0.25, end = 4.0;
  const CameraMotion motion(config, 21, start, end);
  const ImuSampleBuffer buffer =
      test::sampledBuffer(start, end, 4000.0, [&](double t) { return motion.angularVelocity(t); });
  IntegrationOptions options;
  options.interpolation = RateInterpolation::kLinear;
  double worst = 0.0;
  const double pairs[][2] = {{-0.2, 0.0331}, {0.0, 1.0},     {0.51237, 0.54571},
                             {1.1, 3.9},     {2.00001, 2.2}, {-0.25, 4.0}};
  for (const auto& pair : pairs) {
    const IntegrationResult result = integrateRotation(buffer, pair[0], pair[1], options);
    ASSERT_TRUE(result.ok()) << result.reason;
    const Eigen::Matrix3d expected =
        motion.pose(pair[0]).R_world_cam.transpose() * motion.pose(pair[1]).R_world_cam;
    const double error = logSO3(expected.transpose() * result.rotation).norm();
    worst = std::max(worst, error);
    EXPECT_LT(error, 1e-6) << "[" << pair[0] << ", " << pair[1] << "]";
  }
  std::printf("[ figures  ] pose vs integrated 4 kHz gyro: worst %.2e rad\n", worst);
}

TEST(CameraMotion, PoseIsSmoothBetweenGridPoints) {
  // pose() between grid points vs a fine reference integration from the nearest grid point.
  const CameraMotion motion(CameraMotionConfig(), 4, 0.0, 1.0);
  const double h = 1.0 / 4000.0;
  double worst = 0.0;
  for (int k : {100, 1234, 3999}) {
    const double t0 = k * h;
    Eigen::Matrix3d R = motion.pose(t0).R_world_cam;
    const int sub = 1000;
    for (int i = 0; i < sub; ++i) {
      R = R * expSO3(motion.angularVelocity(t0 + (i + 0.5) * h / sub) * (h / sub));
      if ((i + 1) % 250 == 0) {
        const Eigen::Matrix3d interpolated = motion.pose(t0 + (i + 1) * h / sub).R_world_cam;
        worst = std::max(worst, logSO3(R.transpose() * interpolated).norm());
      }
    }
  }
  EXPECT_LT(worst, 1e-10);
}

TEST(CameraMotion, TranslationRmsAndAcceleration) {
  CameraMotionConfig config;
  config.translation_rms_m = 0.01;
  config.translation_band_high_hz = 3.0;
  const double duration = 60.0;  // the band reaches down to 0.3 Hz: a long span for the RMS
  const CameraMotion motion(config, 9, 0.0, duration);
  const int n = static_cast<int>(duration * 100.0);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), square = Eigen::Vector3d::Zero();
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d c = motion.pose(k / 100.0).centre_world_m;
    mean += c;
    square += c.cwiseAbs2();
  }
  mean /= n;
  const Eigen::Vector3d rms = (square / n - mean.cwiseAbs2()).cwiseSqrt();
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(rms[axis], config.translation_rms_m, 0.15 * config.translation_rms_m);
  }
  std::printf("[ figures  ] translation RMS %.4f %.4f %.4f m (config %.4f)\n", rms.x(), rms.y(),
              rms.z(), config.translation_rms_m);
  // The acceleration is the second derivative of the centre (central differences).
  const double h = 1e-3;
  for (double t : {0.5, 7.25, 31.0}) {
    const Eigen::Vector3d numeric =
        (motion.pose(t + h).centre_world_m - 2.0 * motion.pose(t).centre_world_m +
         motion.pose(t - h).centre_world_m) /
        (h * h);
    EXPECT_MATRIX_NEAR(numeric, motion.linearAcceleration(t), 1e-3);
  }
}

TEST(CameraMotion, NoTranslationMeansStillCentre) {
  CameraMotionConfig config;
  config.translation_rms_m = 0.0;
  const CameraMotion motion(config, 2, 0.0, 2.0);
  EXPECT_EQ(Eigen::Vector3d::Zero(), motion.pose(1.3).centre_world_m);
  EXPECT_EQ(Eigen::Vector3d::Zero(), motion.linearAcceleration(1.3));
}

TEST(CameraMotion, ValidateNamesTheField) {
  CameraMotionConfig config;
  EXPECT_EQ("", config.validate());
  config.shake_band_high_hz = 0.5;
  EXPECT_NE(std::string::npos, config.validate().find("shake_band_high_hz"));
  config = CameraMotionConfig();
  config.shake_rms_rad_s.y() = -0.1;
  EXPECT_NE(std::string::npos, config.validate().find("shake_rms_rad_s"));
  config = CameraMotionConfig();
  config.pan_period_s = 0.0;
  EXPECT_NE(std::string::npos, config.validate().find("pan_period_s"));
  config = CameraMotionConfig();
  config.integration_rate_hz = 50.0;
  EXPECT_NE(std::string::npos, config.validate().find("integration_rate_hz"));
  EXPECT_THROW(CameraMotion(config, 1, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(CameraMotion(CameraMotionConfig(), 1, 1.0, 1.0), std::invalid_argument);
}

// A 12.5 s recording's motion and OIS build and give finite poses and lens shifts over the whole
// span. How fast they build is a figure for benchmark_simulator, not a test: a loaded machine
// must not fail it.
TEST(CameraMotion, TwelveSecondsWithOisBuild) {
  const CameraMotion motion(CameraMotionConfig(), 1, -0.25, 12.25);
  const OisModel ois(OisConfig(), motion, 257.0, 2);
  EXPECT_DOUBLE_EQ(-0.25, motion.startTime());
  EXPECT_DOUBLE_EQ(12.25, motion.endTime());
  for (double t = -0.25; t <= 12.25; t += 0.5) {
    EXPECT_TRUE(motion.angularVelocity(t).allFinite()) << "t = " << t;
    EXPECT_TRUE(ois.lensShift(t).allFinite()) << "t = " << t;
    EXPECT_LE(ois.lensShift(t).cwiseAbs().maxCoeff(), ois.strokeLimitPx() + 1e-9) << "t = " << t;
  }
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
