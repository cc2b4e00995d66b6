// The lens-shift log: convention, interpolation, coverage across gaps, and the per-patch
// homographies it gives the gyro flow.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/ois/lens_shift_log.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

LensShiftLogSample sample(double t_s, double x, double y) {
  LensShiftLogSample s;
  s.stamp_s = t_s;
  s.logged = Eigen::Vector2d(x, y);
  return s;
}

TEST(LensShiftLogConvention, ScaleSwapAndSigns) {
  LensShiftLogConvention c;
  c.scale = 0.5;
  c.swap_xy = true;
  c.sign_x = -1.0;
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(-0.5 * 4.0, 0.5 * 2.0), c.toImagePx(Eigen::Vector2d(2.0, 4.0)),
                     1e-12);
  c.sign_y = 0.5;
  EXPECT_NE(c.validate().find("sign_y"), std::string::npos);
  c.sign_y = 1.0;
  c.scale = 0.0;
  EXPECT_NE(c.validate().find("scale"), std::string::npos);
  EXPECT_THROW(LensShiftLog(0.02, c), std::invalid_argument);
  EXPECT_THROW(LensShiftLog(0.0), std::invalid_argument);
}

TEST(LensShiftLog, InterpolatesLinearlyWithConventionAndOffset) {
  LensShiftLogConvention c;
  c.scale = 2.0;
  c.time_offset_s = 0.1;  // logged stamp 0 is camera time 0.1
  LensShiftLog log(0.02, c);
  for (int k = 0; k <= 10; ++k) ASSERT_TRUE(log.add(sample(0.005 * k, k, -k)).accepted());
  EXPECT_TRUE(log.covers(0.1, 0.15));
  EXPECT_FALSE(log.covers(0.099, 0.12));   // before the first sample (camera clock)
  EXPECT_FALSE(log.covers(0.12, 0.1501));  // after the last
  // Camera time 0.1125 = logged 0.0125 = sample 2.5.
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(5.0, -5.0), log.shiftAt(0.1125), 1e-9);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(20.0, -20.0), log.shiftAt(0.15), 1e-9);
  EXPECT_THROW(log.shiftAt(0.2), std::out_of_range);
  EXPECT_DOUBLE_EQ(0.1, log.oldestStampS());
  EXPECT_DOUBLE_EQ(0.15, log.newestStampS());
}

TEST(LensShiftLog, GapLongerThanMaxIsNotCovered) {
  LensShiftLog log(0.012);
  for (double t : {0.0, 0.005, 0.010, 0.015, 0.040, 0.045, 0.050})
    ASSERT_TRUE(log.add(sample(t, t, 0)).accepted());
  EXPECT_TRUE(log.covers(0.001, 0.014));
  EXPECT_FALSE(log.covers(0.001, 0.020));  // spans the 25 ms gap
  EXPECT_FALSE(log.covers(0.030, 0.030));  // inside the gap
  EXPECT_TRUE(log.covers(0.040, 0.050));
  EXPECT_THROW(log.shiftAt(0.02), std::out_of_range);
}

TEST(LensShiftLog, RefusesOutOfOrderDuplicateAndNonFinite) {
  LensShiftLog log;
  ASSERT_TRUE(log.add(sample(1.0, 0, 0)).accepted());
  EXPECT_NE(log.add(sample(1.0, 0, 0)).reason.find("duplicate"), std::string::npos);
  EXPECT_NE(log.add(sample(0.5, 0, 0)).reason.find("out-of-order"), std::string::npos);
  EXPECT_FALSE(log.add(sample(2.0, NAN, 0)).accepted());
  EXPECT_EQ(1u, log.size());
}

TEST(LensShiftLog, DropBeforeKeepsTheBracketingSample) {
  LensShiftLog log;
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(log.add(sample(0.005 * k, k, 0)).accepted());
  log.dropBefore(0.0212);
  EXPECT_TRUE(log.covers(0.0212, 0.03));
  EXPECT_DOUBLE_EQ(0.02, log.oldestStampS());
}

// The patch homographies from a log reproduce K(s(t_b)) R K(s(t_a))^-1 with the exact shift of a
// piecewise-linear trajectory (here linear: interpolation is exact).
TEST(LensLogHomographies, MatchTheLensShiftModelAtPatchTimes) {
  Eigen::Matrix3d K;
  K << 500, 0, 320, 0, 500, 240, 0, 0, 1;
  RollingShutterConfig config;
  config.patch_count = 4;
  config.readout_time_s = 0.02;
  config.time_offset_s = 0.3;  // IMU clock offset: must not move the camera-clock lens times
  LensShiftLog log(0.01);
  auto truth = [](double t) { return Eigen::Vector2d(3.0 + 40.0 * t, -2.0 + 10.0 * t); };
  for (int k = 0; k <= 40; ++k) {
    const double t = 0.005 * k;
    ASSERT_TRUE(log.add({t, truth(t), std::nullopt}).accepted());
  }
  const std::vector<Eigen::Matrix3d> rotations(
      4, Eigen::AngleAxisd(0.01, Eigen::Vector3d(0.3, 1.0, 0.1).normalized()).toRotationMatrix());
  const auto H = lensLogHomographies(K, rotations, log, config, 0.05, 0.0833);
  ASSERT_TRUE(H.has_value());
  for (int i = 0; i < 4; ++i) {
    const double t_a = 0.05 + 0.02 * (i + 0.5) / 4, t_b = 0.0833 + 0.02 * (i + 0.5) / 4;
    const Eigen::Matrix3d expected =
        lensShiftHomographies(K, {rotations[i]}, {truth(t_a)}, {truth(t_b)}).front();
    EXPECT_MATRIX_NEAR(expected, (*H)[i], 1e-9);
  }
  // A pair reaching past the log's end is not covered.
  EXPECT_FALSE(lensLogHomographies(K, rotations, log, config, 0.15, 0.19).has_value());
}

}  // namespace
}  // namespace deep_ois
