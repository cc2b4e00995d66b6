#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"
#include "sim_test_helpers.h"
#include "test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFocalPx = 257.0;  // the default 360 px, 70 degree sensor

Eigen::Matrix3d nominalK() {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 179.5, 0.0, kFocalPx, 134.5, 0.0, 0.0, 1.0;
  return K;
}

CameraMotionConfig shakeOnly(double low_hz, double high_hz) {
  CameraMotionConfig config = test::stillMotionConfig();
  config.shake_band_low_hz = low_hz;
  config.shake_band_high_hz = high_hz;
  config.shake_rms_rad_s = CameraMotionConfig().shake_rms_rad_s;
  return config;
}

// Where the image centre of time t_a is at time t_b: the ray through the centre at t_a (with the
// lens shift of t_a), rotated into the camera of t_b and projected with the shift of t_b. A
// principal-point shift s moves every point by +s, so K(t) = T(s) K and
// p_b = T(s_b) H T(-s_a) c with H = rotationHomography(K, R_b_a).
Eigen::Vector2d centreMotion(const CameraMotion& motion, const OisModel& ois, double t_a,
                             double t_b) {
  const Eigen::Matrix3d R_b_a =
      motion.pose(t_b).R_world_cam.transpose() * motion.pose(t_a).R_world_cam;
  const Eigen::Matrix3d H = rotationHomography(nominalK(), R_b_a);
  const Eigen::Vector2d centre(179.5, 134.5);
  const Eigen::Vector2d p_b =
      test::applyHomography(H, centre - ois.lensShift(t_a)) + ois.lensShift(t_b);
  return p_b - centre;
}

// RMS of the frame-to-frame (30 Hz) image motion of the centre with the OIS, over that without.
double residualRatio(const CameraMotion& motion, const OisModel& ois, const OisModel& off) {
  double with = 0.0, without = 0.0;
  for (double t = 1.0; t < motion.endTime() - 0.1; t += 0.01) {
    with += centreMotion(motion, ois, t, t + 1.0 / 30.0).squaredNorm();
    without += centreMotion(motion, off, t, t + 1.0 / 30.0).squaredNorm();
  }
  return std::sqrt(with / without);
}

TEST(OisModel, DisabledIsZeroEverywhere) {
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 3.0);
  OisConfig config;
  config.enabled = false;
  const OisModel ois(config, motion, kFocalPx, 2);
  EXPECT_FALSE(ois.enabled());
  EXPECT_NEAR(kFocalPx * std::tan(kPi / 180.0), ois.strokeLimitPx(), 1e-12);
  for (double t : {-1.0, 0.0, 0.7, 2.9, 5.0}) EXPECT_EQ(Eigen::Vector2d::Zero(), ois.lensShift(t));
}

TEST(OisModel, DeterministicPerSeed) {
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 3.0);
  const OisModel a(OisConfig(), motion, kFocalPx, 5), b(OisConfig(), motion, kFocalPx, 5);
  const OisModel c(OisConfig(), motion, kFocalPx, 6);
  double differs = 0.0;
  for (double t = 0.0; t < 3.0; t += 0.0123) {
    EXPECT_EQ(a.lensShift(t), b.lensShift(t));
    differs = std::max(differs, (a.lensShift(t) - c.lensShift(t)).norm());
  }
  EXPECT_GT(differs, 0.0);   // the stabilizer gyro noise depends on the seed
  EXPECT_LT(differs, 0.05);  // and is small
}

TEST(OisModel, IgnoresRoll) {
  CameraMotionConfig roll = test::stillMotionConfig();
  roll.shake_rms_rad_s = Eigen::Vector3d(0.0, 0.0, 0.3);
  const CameraMotion rolling(roll, 3, 0.0, 4.0), resting(test::stillMotionConfig(), 3, 0.0, 4.0);
  // Without gyro noise: no shift at all.
  OisConfig quiet;
  quiet.gyro_noise_rad_s = 0.0;
  const OisModel quiet_ois(quiet, rolling, kFocalPx, 4);
  // With gyro noise: exactly what a camera at rest gets from the same noise.
  const OisModel noisy_rolling(OisConfig(), rolling, kFocalPx, 4);
  const OisModel noisy_resting(OisConfig(), resting, kFocalPx, 4);
  double noise_max = 0.0;
  for (double t = 0.0; t <= 4.0; t += 1e-3) {
    EXPECT_EQ(Eigen::Vector2d::Zero(), quiet_ois.lensShift(t));
    EXPECT_EQ(noisy_resting.lensShift(t), noisy_rolling.lensShift(t));
    noise_max = std::max(noise_max, noisy_rolling.lensShift(t).norm());
  }
  EXPECT_GT(noise_max, 0.0);
  EXPECT_GT(rolling.angularVelocity(1.0).norm(), 0.01);
}

// The sign of the cancelling shift, against the core's rotationHomography: with no centring, a
// near-ideal actuator and a rotation about one axis, the direction at the image centre at the
// start stays at the centre.
TEST(OisModel, ShiftCancelsRotationAboutEachAxis) {
  OisConfig ideal;
  ideal.highpass_corner_hz = 0.0;
  ideal.actuator_natural_hz = 1000.0;
  ideal.control_rate_hz = 20000.0;
  ideal.stroke_limit_deg = 20.0;
  ideal.gyro_noise_rad_s = 0.0;
  for (int axis = 0; axis < 2; ++axis) {
    CameraMotionConfig config = test::stillMotionConfig();
    config.shake_rms_rad_s[axis] = 0.3;
    const CameraMotion motion(config, 8, 0.0, 2.0);
    const OisModel ois(ideal, motion, kFocalPx, 1);
    OisConfig off = ideal;
    off.enabled = false;
    const OisModel none(off, motion, kFocalPx, 1);
    double worst = 0.0, largest_uncompensated = 0.0;
    for (double t = 0.05; t <= 2.0; t += 0.01) {
      worst = std::max(worst, centreMotion(motion, ois, 0.0, t).norm());
      largest_uncompensated =
          std::max(largest_uncompensated, centreMotion(motion, none, 0.0, t).norm());
    }
    EXPECT_GT(largest_uncompensated, 3.0) << "axis " << axis;
    EXPECT_LT(worst, 0.02 * largest_uncompensated) << "axis " << axis;
    std::printf("[ figures  ] axis %d: ideal OIS residual %.4f px of %.2f px\n", axis, worst,
                largest_uncompensated);
  }
}

TEST(OisModel, CancelsMostShakeInsideItsBand) {
  const OisConfig config;
  OisConfig off = config;
  off.enabled = false;
  // Shake well inside the stabilizer's band (above the centring corner, below the actuator).
  const CameraMotion inside(shakeOnly(2.0, 8.0), 12, -0.25, 12.0);
  const double ratio_inside = residualRatio(inside, OisModel(config, inside, kFocalPx, 1),
                                            OisModel(off, inside, kFocalPx, 1));
  EXPECT_LT(ratio_inside, 0.2);
  // The default 1-12 Hz shake: the band edges are where the centring and the actuator lag cost.
  const CameraMotion wide(shakeOnly(1.0, 12.0), 12, -0.25, 12.0);
  const double ratio_wide =
      residualRatio(wide, OisModel(config, wide, kFocalPx, 1), OisModel(off, wide, kFocalPx, 1));
  EXPECT_LT(ratio_wide, 0.3);
  // A shake far above the actuator's natural frequency is hardly reduced (nor much amplified).
  CameraMotionConfig fast_config = shakeOnly(90.0, 110.0);
  fast_config.integration_rate_hz = 4000.0;
  const CameraMotion fast(fast_config, 12, -0.25, 4.0);
  const double ratio_fast =
      residualRatio(fast, OisModel(config, fast, kFocalPx, 1), OisModel(off, fast, kFocalPx, 1));
  EXPECT_GT(ratio_fast, 0.8);
  std::printf(
      "[ figures  ] residual / uncompensated centre motion (30 Hz pairs): 2-8 Hz shake "
      "%.3f, 1-12 Hz %.3f, 90-110 Hz %.3f\n",
      ratio_inside, ratio_wide, ratio_fast);
}

// A PI position loop stabilises as well inside the band, differs from the second-order actuator,
// and is refused with a sentence when misconfigured.
TEST(OisModel, PiPositionLoopStabilisesAndDiffersFromTheSecondOrderLoop) {
  OisConfig pi;
  pi.position_loop = "pi";
  OisConfig off = pi;
  off.enabled = false;
  const CameraMotion inside(shakeOnly(2.0, 8.0), 12, -0.25, 12.0);
  const double ratio = residualRatio(inside, OisModel(pi, inside, kFocalPx, 1), OisModel(off, inside, kFocalPx, 1));
  EXPECT_LT(ratio, 0.25);
  const OisModel with_pi(pi, inside, kFocalPx, 1), second_order(OisConfig(), inside, kFocalPx, 1);
  double largest_difference = 0.0;
  for (double t = 1.0; t < 11.0; t += 0.01)
    largest_difference = std::max(largest_difference, (with_pi.lensShift(t) - second_order.lensShift(t)).norm());
  EXPECT_GT(largest_difference, 0.05);
  std::printf("[ figures  ] PI loop: residual / uncompensated %.3f, largest difference to the second-order loop %.3f px\n",
              ratio, largest_difference);
  OisConfig bad = pi;
  bad.position_loop = "pid";
  EXPECT_NE(bad.validate().find("position_loop"), std::string::npos);
  bad = pi;
  bad.pi_kp = 0.0;
  EXPECT_NE(bad.validate().find("pi_kp"), std::string::npos);
}

// A slow pan: the high-passed angle follows the quasi-static response instead of the growing
// pan angle, so the lens stays near centre and returns to it when the pan rate does.
TEST(OisModel, CentresDuringSlowPans) {
  CameraMotionConfig config = test::stillMotionConfig();
  config.pan_peak_rad_s = 0.05;
  config.pan_period_s = 6.0;
  const CameraMotion motion(config, 17, 0.0, 12.0);
  OisConfig ois_config;
  ois_config.gyro_noise_rad_s = 0.0;
  const OisModel ois(ois_config, motion, kFocalPx, 1);

  // Reference high-pass: theta' = w - wc theta by RK4 at 1 kHz.
  const double wc = 2.0 * kPi * ois_config.highpass_corner_hz, h = 1e-3;
  Eigen::Vector2d theta = Eigen::Vector2d::Zero();
  auto f = [&](double t, const Eigen::Vector2d& y) -> Eigen::Vector2d {
    return Eigen::Vector2d(motion.angularVelocity(t).head<2>()) - wc * y;
  };
  double worst = 0.0, largest = 0.0, largest_raw = 0.0;
  Eigen::Vector2d raw = Eigen::Vector2d::Zero();  // the plain integrated angle
  for (int k = 0; k < 12000; ++k) {
    const double t = k * h;
    const Eigen::Vector2d k1 = f(t, theta), k2 = f(t + h / 2, theta + h / 2 * k1),
                          k3 = f(t + h / 2, theta + h / 2 * k2), k4 = f(t + h, theta + h * k3);
    theta += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    raw += h * motion.angularVelocity(t + h / 2).head<2>();
    const Eigen::Vector2d expected(kFocalPx * std::tan(theta.y()), -kFocalPx * std::tan(theta.x()));
    const Eigen::Vector2d shift = ois.lensShift(t + h);
    worst = std::max(worst, (shift - expected).norm());
    largest = std::max(largest, shift.norm());
    largest_raw = std::max(largest_raw, kFocalPx * std::tan(raw.norm()));
    EXPECT_LE(shift.cwiseAbs().maxCoeff(), ois.strokeLimitPx() + 1e-12);
  }
  EXPECT_LT(worst, 0.02 * largest);
  EXPECT_LT(largest, 0.2 * largest_raw);
  // The pans end at rest at t = 6 and 12 s: the lens is back near the centre.
  EXPECT_LT(ois.lensShift(6.0).norm(), 0.1 * largest);
  EXPECT_LT(ois.lensShift(12.0).norm(), 0.1 * largest);
  std::printf(
      "[ figures  ] slow pan: largest shift %.2f px (the raw angle would ask %.1f px), "
      "at pan ends %.3f / %.3f px\n",
      largest, largest_raw, ois.lensShift(6.0).norm(), ois.lensShift(12.0).norm());
}

TEST(OisModel, NeverExceedsTheStroke) {
  CameraMotionConfig config;  // shake plus fast pans that drive the lens into its end stops
  config.pan_peak_rad_s = 0.5;
  config.pan_period_s = 2.0;
  const CameraMotion motion(config, 4, 0.0, 8.0);
  const OisModel ois(OisConfig(), motion, kFocalPx, 1);
  double largest = 0.0;
  for (double t = 0.0; t <= 8.0; t += 1.0 / 8000.0) {
    largest = std::max(largest, ois.lensShift(t).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(largest, ois.strokeLimitPx());
  EXPECT_GT(largest, 0.999 * ois.strokeLimitPx());  // it did hit the end stop
}

TEST(OisModel, LensShiftInterpolatesAndHolds) {
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 1.0);
  OisConfig config;
  config.control_rate_hz = 1000.0;
  const OisModel ois(config, motion, kFocalPx, 1);
  const Eigen::Vector2d a = ois.lensShift(0.500), b = ois.lensShift(0.501);
  EXPECT_MATRIX_NEAR(0.75 * a + 0.25 * b, ois.lensShift(0.50025), 1e-12);
  EXPECT_EQ(Eigen::Vector2d::Zero(), ois.lensShift(-0.5));  // starts centred, held before
  EXPECT_EQ(ois.lensShift(1.0), ois.lensShift(3.0));
}

// Step response of the exact discretisation against the analytic one.
TEST(OisActuator, StepResponseMatchesSecondOrderSystem) {
  for (double damping : {0.7, 0.3, 1.0, 2.0}) {
    const double natural_hz = 35.0, dt = 1.0 / 4000.0;
    LensActuator actuator(natural_hz, damping, dt, 100.0);
    const double wn = 2.0 * kPi * natural_hz;
    double peak = 0.0, settled_at = 0.0, worst = 0.0;
    for (int k = 1; k <= 800; ++k) {
      const double x = actuator.advance(1.0);
      const double t = k * dt;
      double expected;
      if (damping < 1.0) {
        const double wd = wn * std::sqrt(1.0 - damping * damping);
        expected = 1.0 - std::exp(-damping * wn * t) *
                             (std::cos(wd * t) + damping * wn / wd * std::sin(wd * t));
      } else if (damping == 1.0) {
        expected = 1.0 - std::exp(-wn * t) * (1.0 + wn * t);
      } else {
        const double root = std::sqrt(damping * damping - 1.0);
        const double p1 = wn * (damping - root), p2 = wn * (damping + root);
        expected = 1.0 - (p2 * std::exp(-p1 * t) - p1 * std::exp(-p2 * t)) / (p2 - p1);
      }
      worst = std::max(worst, std::abs(x - expected));
      peak = std::max(peak, x);
      if (std::abs(x - 1.0) > 0.02) settled_at = t;
    }
    EXPECT_LT(worst, 1e-9) << "damping " << damping;
    const double overshoot = peak - 1.0;
    if (damping < 1.0) {
      const double theory = std::exp(-damping * kPi / std::sqrt(1.0 - damping * damping));
      EXPECT_NEAR(theory, overshoot, 1e-3) << "damping " << damping;
    } else {
      EXPECT_LE(overshoot, 1e-12) << "damping " << damping;
    }
    if (damping == 0.7) {
      // 2 % settling ~ 4 / (zeta wn) = 26 ms, i.e. about one natural period.
      EXPECT_GT(settled_at, 0.5 / natural_hz);
      EXPECT_LT(settled_at, 1.5 / natural_hz);
      std::printf(
          "[ figures  ] actuator 35 Hz, zeta 0.7: overshoot %.2f %%, 2 %% settling %.1f ms"
          "\n",
          100.0 * overshoot, 1e3 * settled_at);
    }
  }
}

TEST(OisActuator, StopsAtTheEndStop) {
  LensActuator actuator(35.0, 0.7, 1.0 / 4000.0, 2.0);
  for (int k = 0; k < 400; ++k) EXPECT_LE(std::abs(actuator.advance(5.0)), 2.0);
  EXPECT_EQ(2.0, actuator.positionPx());
  EXPECT_EQ(0.0, actuator.velocityPxPerS());
  // And comes back off it when commanded.
  for (int k = 0; k < 400; ++k) actuator.advance(0.0);
  EXPECT_NEAR(0.0, actuator.positionPx(), 0.02);
  // A long step is still exact (and stable).
  LensActuator coarse(35.0, 0.7, 0.5, 100.0);
  EXPECT_NEAR(1.0, coarse.advance(1.0), 1e-6);
  EXPECT_THROW(LensActuator(0.0, 0.7, 1e-3, 1.0), std::invalid_argument);
}

TEST(OisModel, ValidateNamesTheField) {
  EXPECT_EQ("", OisConfig().validate());
  OisConfig config;
  config.actuator_damping = 0.0;
  EXPECT_NE(std::string::npos, config.validate().find("actuator_damping"));
  config = OisConfig();
  config.stroke_limit_deg = -1.0;
  EXPECT_NE(std::string::npos, config.validate().find("stroke_limit_deg"));
  config = OisConfig();
  config.control_rate_hz = 100.0;
  EXPECT_NE(std::string::npos, config.validate().find("control_rate_hz"));
  config = OisConfig();
  config.highpass_corner_hz = std::nan("");
  EXPECT_NE(std::string::npos, config.validate().find("highpass_corner_hz"));
  const CameraMotion motion(test::stillMotionConfig(), 1, 0.0, 1.0);
  EXPECT_THROW(OisModel(config, motion, kFocalPx, 1), std::invalid_argument);
  EXPECT_THROW(OisModel(OisConfig(), motion, 0.0, 1), std::invalid_argument);
}


// ---- Stabiliser variety -----------------------------------------------------------------------

// Largest lens excursion over the motion, per axis and as a radius, pixels.
Eigen::Vector3d largestShift(const OisModel& ois, double end_s) {
  Eigen::Vector3d largest = Eigen::Vector3d::Zero();
  for (double t = 0.0; t < end_s; t += 0.002) {
    const Eigen::Vector2d s = ois.lensShift(t);
    largest = largest.cwiseMax(Eigen::Vector3d(std::abs(s.x()), std::abs(s.y()), s.norm()));
  }
  return largest;
}

TEST(OisModel, AsymmetricAndCircularStrokesBoundTheLens) {
  CameraMotionConfig config = test::stillMotionConfig();
  config.pan_peak_rad_s = 0.4;  // pans far beyond the stroke: the lens sits at its end stops
  config.pan_period_s = 2.0;
  config.shake_rms_rad_s = Eigen::Vector3d(0.3, 0.3, 0.0);
  const CameraMotion motion(config, 4, 0.0, 6.0);
  OisConfig box;
  box.stroke_limit_deg = 1.0;
  box.stroke_limit_y_deg = 0.5;
  const OisModel asymmetric(box, motion, kFocalPx, 1);
  const Eigen::Vector3d box_largest = largestShift(asymmetric, 6.0);
  EXPECT_NEAR(asymmetric.strokeLimitYPx(), kFocalPx * std::tan(0.5 * kPi / 180.0), 1e-9);
  EXPECT_LE(box_largest.x(), asymmetric.strokeLimitPx() + 1e-9);
  EXPECT_LE(box_largest.y(), asymmetric.strokeLimitYPx() + 1e-9);
  EXPECT_GT(box_largest.x(), 0.9 * asymmetric.strokeLimitPx());  // it does reach its end stops
  EXPECT_GT(box_largest.y(), 0.9 * asymmetric.strokeLimitYPx());

  OisConfig circle;
  circle.stroke_shape = StrokeShape::kCircle;
  const OisModel round(circle, motion, kFocalPx, 1);
  OisConfig square;
  const OisModel boxed(square, motion, kFocalPx, 1);
  // A box lets the corner reach sqrt(2) x the limit; a circle keeps the radius near the limit
  // (the commands are clamped radially; the per-axis end stops only catch overshoot).
  EXPECT_GT(largestShift(boxed, 6.0).z(), 1.2 * boxed.strokeLimitPx());
  EXPECT_LT(largestShift(round, 6.0).z(), 1.1 * round.strokeLimitPx());
}

TEST(OisModel, PanDetectionLetsGoDuringADeliberatePan) {
  CameraMotionConfig config = test::stillMotionConfig();
  config.pan_peak_rad_s = 0.3;
  config.pan_period_s = 3.0;
  const CameraMotion motion(config, 2, 0.0, 6.0);
  OisConfig holding;
  holding.stroke_limit_deg = 3.0;  // wide, so the end stop does not hide the difference
  OisConfig releasing = holding;
  releasing.pan_detection_rate_rad_s = 0.1;
  releasing.pan_release_corner_hz = 5.0;
  const OisModel hold(holding, motion, kFocalPx, 3), release(releasing, motion, kFocalPx, 3);
  const double hold_px = largestShift(hold, 6.0).z(), release_px = largestShift(release, 6.0).z();
  std::printf("[ figures  ] pan 0.3 rad/s: largest lens excursion %.2f px holding, %.2f px with "
              "pan detection\n", hold_px, release_px);
  EXPECT_LT(release_px, 0.5 * hold_px);
}

TEST(OisModel, HallSensorNoiseAndLag) {
  const CameraMotion motion(shakeOnly(1.0, 12.0), 5, 0.0, 4.0);
  OisConfig clean;
  OisConfig noisy = clean;
  noisy.hall_noise_px = 0.2;
  OisConfig late = clean;
  late.hall_lag_s = 0.01;
  const OisModel a(clean, motion, kFocalPx, 9), b(noisy, motion, kFocalPx, 9),
      c(late, motion, kFocalPx, 9);
  // Noise: the lens jitters around the clean trajectory (the 35 Hz actuator filters it).
  double jitter = 0.0;
  int n = 0;
  for (double t = 0.5; t < 3.5; t += 0.001, ++n) jitter += (b.lensShift(t) - a.lensShift(t)).squaredNorm();
  jitter = std::sqrt(jitter / n);
  EXPECT_GT(jitter, 0.01);
  EXPECT_LT(jitter, 0.2);
  // Lag: the lagged lens is the clean one 10 ms later, closely.
  double lagged = 0.0, unlagged = 0.0;
  for (double t = 0.5; t < 3.5; t += 0.001) {
    lagged += (c.lensShift(t) - a.lensShift(t - 0.01)).squaredNorm();
    unlagged += (c.lensShift(t) - a.lensShift(t)).squaredNorm();
  }
  EXPECT_LT(lagged, 0.05 * unlagged);
  // The default configuration keeps its trajectory (no extra random draws).
  const OisModel again(OisConfig(), motion, kFocalPx, 9);
  for (double t = 0.0; t < 4.0; t += 0.1) EXPECT_EQ(a.lensShift(t), again.lensShift(t));
}

TEST(OisModel, UnderAndOverCompensation) {
  const CameraMotion motion(shakeOnly(1.0, 12.0), 6, 0.0, 4.0);
  OisConfig off;
  off.enabled = false;
  const OisModel none(off, motion, kFocalPx, 1);
  double previous_ratio = 0.0;
  for (const double gain : {0.5, 1.0}) {
    OisConfig config;
    config.gain = gain;
    config.stroke_limit_deg = 3.0;
    const double ratio = residualRatio(motion, OisModel(config, motion, kFocalPx, 1), none);
    if (previous_ratio > 0.0) {
      EXPECT_LT(ratio, previous_ratio);  // more gain cancels more
    }
    previous_ratio = ratio;
  }
  OisConfig over;
  over.gain = 1.8;
  over.stroke_limit_deg = 3.0;
  OisConfig exact = over;
  exact.gain = 1.0;
  // Over-compensation moves the image the other way: worse than the right gain.
  EXPECT_GT(residualRatio(motion, OisModel(over, motion, kFocalPx, 1), none),
            residualRatio(motion, OisModel(exact, motion, kFocalPx, 1), none));
}

TEST(OisModel, FollowsALensShiftLog) {
  const std::string path = ::testing::TempDir() + "/lens_log.csv";
  {
    std::ofstream csv(path);
    csv << "t_s,x_px,y_px\n0.0,0.0,0.0\n1.0,2.0,-1.0\n2.0,0.0,4.0\n";
  }
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 3.0);
  OisConfig config;
  config.lens_shift_csv = path;
  const OisModel ois(config, motion, kFocalPx, 1);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(1.0, -0.5), ois.lensShift(0.5), 1e-9);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(1.0, 1.5), ois.lensShift(1.5), 1e-9);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(0.0, 4.0), ois.lensShift(2.7), 1e-9);  // held after the log
  {
    std::ofstream csv(path);
    csv << "t_s,x_px,y_px\n0.0,0.0,0.0\n0.5,two,1.0\n";
  }
  try {
    OisModel bad(config, motion, kFocalPx, 1);
    FAIL() << "a malformed lens log was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lens_log.csv:3"), std::string::npos) << e.what();
  }
}

TEST(OisModel, ValidatesTheNewFields) {
  OisConfig config;
  config.stroke_limit_y_deg = -1.0;
  EXPECT_NE(config.validate().find("stroke_limit_y_deg"), std::string::npos);
  config = OisConfig();
  config.hall_lag_s = 0.5;
  EXPECT_NE(config.validate().find("hall_lag_s"), std::string::npos);
  config = OisConfig();
  config.pan_release_corner_hz = 0.0;
  EXPECT_NE(config.validate().find("pan_release_corner_hz"), std::string::npos);
  StrokeShape shape;
  EXPECT_TRUE(parseStrokeShape("circle", &shape));
  EXPECT_EQ(StrokeShape::kCircle, shape);
  EXPECT_FALSE(parseStrokeShape("square", &shape));
}

// ---- The controller family (the stages of core/sim/stabiliser_design_runner.h) ----

// The intended-motion estimator stabilises a shake inside its band as the high-pass does, and its
// manoeuvre gate lets go during a deliberate pan.
TEST(OisController, KalmanEstimatorStabilisesAndItsGateLetsGoAtAPan) {
  OisConfig kalman;
  kalman.controller = "kalman";
  kalman.kalman_bandwidth_hz = 0.5;
  OisConfig off;
  off.enabled = false;
  const CameraMotion shake(shakeOnly(2.0, 8.0), 12, -0.25, 8.0);
  const double ratio = residualRatio(shake, OisModel(kalman, shake, kFocalPx, 1),
                                     OisModel(off, shake, kFocalPx, 1));
  EXPECT_LT(ratio, 0.25);
  // Not the high-pass under another name.
  const OisModel highpass(OisConfig(), shake, kFocalPx, 1), estimator(kalman, shake, kFocalPx, 1);
  double difference = 0.0;
  for (double t = 1.0; t < 7.0; t += 0.01) difference += (highpass.lensShift(t) - estimator.lensShift(t)).norm();
  EXPECT_GT(difference / 600.0, 0.05);

  CameraMotionConfig pan_config = test::stillMotionConfig();
  pan_config.pan_peak_rad_s = 0.3;
  pan_config.pan_period_s = 3.0;
  const CameraMotion pan(pan_config, 2, 0.0, 6.0);
  kalman.stroke_limit_deg = 5.0;  // wide, so the end stop does not hide the difference
  OisConfig gated = kalman;
  gated.kalman_manoeuvre_deg = 0.3;
  const double held = largestShift(OisModel(kalman, pan, kFocalPx, 3), 6.0).z();
  const double released = largestShift(OisModel(gated, pan, kFocalPx, 3), 6.0).z();
  std::printf("[ figures  ] kalman: 2-8 Hz residual ratio %.3f; pan excursion %.2f px, gated %.2f px\n",
              ratio, held, released);
  EXPECT_LT(released, 0.7 * held);
}

// Excursion-dependent re-centring pulls the lens back harder the further out it is; a soft stroke
// approaches the limit without a corner and never passes it.
TEST(OisController, ExcursionRecentringAndSoftStroke) {
  CameraMotionConfig pan_config = test::stillMotionConfig();
  pan_config.pan_peak_rad_s = 0.3;
  pan_config.pan_period_s = 3.0;
  const CameraMotion pan(pan_config, 2, 0.0, 6.0);
  OisConfig plain;
  plain.highpass_corner_hz = 0.3;
  plain.stroke_limit_deg = 5.0;
  OisConfig pulled = plain;
  pulled.excursion_recentring_gain = 20.0;
  const double plain_px = largestShift(OisModel(plain, pan, kFocalPx, 3), 6.0).z();
  const double pulled_px = largestShift(OisModel(pulled, pan, kFocalPx, 3), 6.0).z();
  EXPECT_LT(pulled_px, 0.8 * plain_px);
  // Small shakes (far from the stroke) are stabilised about as without it.
  const CameraMotion shake(shakeOnly(2.0, 8.0), 12, -0.25, 6.0);
  OisConfig off;
  off.enabled = false;
  const OisModel none(off, shake, kFocalPx, 1);
  EXPECT_LT(residualRatio(shake, OisModel(pulled, shake, kFocalPx, 1), none),
            1.2 * residualRatio(shake, OisModel(plain, shake, kFocalPx, 1), none));

  OisConfig hard;
  hard.stroke_limit_deg = 0.3;
  OisConfig soft = hard;
  soft.soft_stroke = true;
  const OisModel hard_model(hard, pan, kFocalPx, 3), soft_model(soft, pan, kFocalPx, 3);
  const double limit_px = hard_model.strokeLimitPx();
  const Eigen::Vector3d soft_largest = largestShift(soft_model, 6.0);
  EXPECT_LE(soft_largest.x(), limit_px * (1.0 + 1e-9));
  EXPECT_LE(soft_largest.y(), limit_px * (1.0 + 1e-9));
  double difference = 0.0;
  for (double t = 0.5; t < 6.0; t += 0.01) difference += (hard_model.lensShift(t) - soft_model.lensShift(t)).norm();
  EXPECT_GT(difference / 550.0, 0.02 * limit_px);
  std::printf("[ figures  ] pan excursion %.2f px, with excursion re-centring %.2f px; soft stroke "
              "largest %.3f of the stroke\n", plain_px, pulled_px, soft_largest.head<2>().maxCoeff() / limit_px);
}

// A digital controller: its command is held between updates at its own rate and quantised to its
// least significant bit; its delay shows as a lens that follows late.
TEST(OisController, DigitalLoopHoldsQuantisesAndDelays) {
  OisConfig config;
  config.command_lsb_deg = 0.05;
  config.control_rate_hz = 1000.0;
  // The module's stages (its travel stage quantises) on a steady rate.
  StabiliserChain chain(stabiliserRunners(moduleModel(config), {kFocalPx, 0.001}));
  chain.reset();
  const double lsb_px = kFocalPx * std::tan(0.05 * kPi / 180.0);
  double largest_px = 0.0;
  for (int k = 0; k < 200; ++k) {
    chain.step(Eigen::Vector3d(0.2, -0.1, 0.0), Eigen::Vector3d(0.2, -0.1, 0.0));
    const Eigen::Vector2d c = chain.signal().command_px;
    EXPECT_NEAR(c.x() / lsb_px, std::round(c.x() / lsb_px), 1e-9);
    EXPECT_NEAR(c.y() / lsb_px, std::round(c.y() / lsb_px), 1e-9);
    largest_px = std::max(largest_px, c.cwiseAbs().maxCoeff());
  }
  EXPECT_GT(largest_px, 3.0 * lsb_px);  // it moved over several steps of the DAC
  const CameraMotion shake(shakeOnly(1.0, 12.0), 5, 0.0, 4.0);
  OisConfig digital;
  digital.digital_rate_hz = 500.0;
  OisConfig late = digital;
  late.digital_delay_s = 0.01;
  const OisModel a(digital, shake, kFocalPx, 9), b(late, shake, kFocalPx, 9),
      continuous(OisConfig(), shake, kFocalPx, 9);
  double lagged = 0.0, unlagged = 0.0, to_continuous = 0.0;
  for (double t = 0.5; t < 3.5; t += 0.001) {
    lagged += (b.lensShift(t) - a.lensShift(t - 0.01)).squaredNorm();
    unlagged += (b.lensShift(t) - a.lensShift(t)).squaredNorm();
    to_continuous += (a.lensShift(t) - continuous.lensShift(t)).squaredNorm();
  }
  EXPECT_LT(lagged, 0.05 * unlagged);
  EXPECT_GT(to_continuous, 0.0);  // a 500 Hz loop is not the continuous one
  OisConfig off;
  off.enabled = false;
  EXPECT_LT(residualRatio(shake, a, OisModel(off, shake, kFocalPx, 9)), 0.35);
}

// A rotated gyro mount cancels the wrong direction partly; cross-coupling mixes the lens axes.
TEST(OisController, RotatedAndCrossCoupledMount) {
  const CameraMotion shake(shakeOnly(2.0, 8.0), 12, -0.25, 6.0);
  OisConfig off;
  off.enabled = false;
  const OisModel none(off, shake, kFocalPx, 1);
  OisConfig aligned;
  aligned.stroke_limit_deg = 3.0;
  OisConfig turned = aligned;
  turned.mount_rotation_deg = 30.0;
  OisConfig coupled = aligned;
  coupled.actuator_cross_coupling = 0.3;
  const double r_aligned = residualRatio(shake, OisModel(aligned, shake, kFocalPx, 1), none);
  const double r_turned = residualRatio(shake, OisModel(turned, shake, kFocalPx, 1), none);
  const double r_coupled = residualRatio(shake, OisModel(coupled, shake, kFocalPx, 1), none);
  std::printf("[ figures  ] residual ratio aligned %.3f, gyro turned 30 deg %.3f, 30 %% cross-coupled %.3f\n",
              r_aligned, r_turned, r_coupled);
  // A 30 degree turn leaves |1 - exp(i 30 deg)| = 0.52 of the motion (at least).
  EXPECT_GT(r_turned, 0.45);
  EXPECT_GT(r_coupled, r_aligned + 0.1);
}

TEST(OisController, ValidateNamesTheNewFields) {
  auto problem = [](auto edit) {
    OisConfig c;
    edit(c);
    return c.validate();
  };
  EXPECT_NE(problem([](OisConfig& c) { c.controller = "pid"; }).find("controller"), std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.controller = "kalman"; c.kalman_bandwidth_hz = 0.0; })
                .find("kalman_bandwidth_hz"), std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.kalman_manoeuvre_factor = 0.5; }).find("kalman_manoeuvre"),
            std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.excursion_recentring_gain = -1.0; })
                .find("excursion_recentring"), std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.digital_rate_hz = 1e5; }).find("digital_rate_hz"),
            std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.digital_delay_s = 0.2; }).find("digital_delay_s"),
            std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.command_lsb_deg = -0.1; }).find("command_lsb_deg"),
            std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.mount_rotation_deg = 90.0; }).find("mount_rotation_deg"),
            std::string::npos);
  EXPECT_NE(problem([](OisConfig& c) { c.actuator_cross_coupling = 0.9; })
                .find("actuator_cross_coupling"), std::string::npos);
  EXPECT_EQ(problem([](OisConfig&) {}), "");
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
