#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

using test::sampledBuffer;

Eigen::Matrix3d axisAngle(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
}

// Reference solution of dR/dt = R [w(t)]x by many tiny exponential-map steps.
template <typename RateFunction>
Eigen::Matrix3d fineStepReference(double t0, double t1, RateFunction rate) {
  const int steps = 200000;
  const double dt = (t1 - t0) / steps;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int k = 0; k < steps; ++k) R = R * expSO3(rate(t0 + (k + 0.5) * dt) * dt);
  return R;
}

TEST(ExpSO3, MatchesAngleAxisAndLogInverts) {
  const Eigen::Vector3d v(0.3, -0.2, 0.7);
  EXPECT_MATRIX_NEAR(axisAngle(v.norm(), v), expSO3(v), 1e-14);
  EXPECT_MATRIX_NEAR(v, logSO3(expSO3(v)), 1e-12);
  const Eigen::Vector3d tiny(1e-9, 2e-9, -3e-9);
  EXPECT_MATRIX_NEAR(axisAngle(tiny.norm(), tiny), expSO3(tiny), 1e-16);
}

TEST(IntegrateRotation, ConstantRateIsExactInBothModes) {
  const Eigen::Vector3d w(0.2, -0.5, 1.1);
  const ImuSampleBuffer buffer = sampledBuffer(0.0, 1.0, 400.0, [&](double) { return w; });
  for (auto mode : {RateInterpolation::kLinear, RateInterpolation::kZeroOrderHold}) {
    IntegrationOptions options;
    options.interpolation = mode;
    // Arbitrary times between samples.
    const IntegrationResult result = integrateRotation(buffer, 0.1234, 0.4567, options);
    ASSERT_TRUE(result.ok()) << result.reason;
    EXPECT_MATRIX_NEAR(expSO3(w * (0.4567 - 0.1234)), result.rotation, 1e-12);
  }
}

TEST(IntegrateRotation, LinearModeFollowsAVaryingRate) {
  // Rate whose direction turns: the coning term matters here.
  auto rate = [](double t) {
    return Eigen::Vector3d(0.4 * std::sin(9.0 * t), 0.5 * std::cos(7.0 * t), 0.3 + 0.2 * t);
  };
  const ImuSampleBuffer buffer = sampledBuffer(0.0, 1.0, 400.0, rate);
  IntegrationOptions options;
  const IntegrationResult result = integrateRotation(buffer, 0.05, 0.2, options);
  ASSERT_TRUE(result.ok()) << result.reason;
  // Piecewise-linear interpolation of a smooth rate at 400 Hz: error ~ dt^2 * w'' ~ 1e-6 rad.
  EXPECT_LT(logSO3(fineStepReference(0.05, 0.2, rate).transpose() * result.rotation).norm(), 3e-6);
}

TEST(IntegrateRotation, LinearModeIsExactForPiecewiseLinearRateOfFixedAxis) {
  // w(t) = (0, 0, 2t) sampled at 100 Hz is exactly piecewise linear: angle = t^2.
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 1.0, 100.0, [](double t) { return Eigen::Vector3d(0, 0, 2.0 * t); });
  const IntegrationResult result = integrateRotation(buffer, 0.105, 0.733, IntegrationOptions{});
  ASSERT_TRUE(result.ok()) << result.reason;
  EXPECT_MATRIX_NEAR(axisAngle(0.733 * 0.733 - 0.105 * 0.105, Eigen::Vector3d::UnitZ()),
                     result.rotation, 1e-12);
}

TEST(IntegrateRotation, ZeroOrderHoldHoldsTheEarlierSample) {
  ImuSampleBuffer buffer(10.0);
  ASSERT_TRUE(buffer.add({0.0, Eigen::Vector3d(0, 0, 1.0)}).accepted());
  ASSERT_TRUE(buffer.add({0.01, Eigen::Vector3d(0, 0, 3.0)}).accepted());
  ASSERT_TRUE(buffer.add({0.02, Eigen::Vector3d(0, 0, 5.0)}).accepted());
  IntegrationOptions zoh;
  zoh.interpolation = RateInterpolation::kZeroOrderHold;
  // [0.005, 0.015]: 0.005 s at 1 rad/s then 0.005 s at 3 rad/s.
  const IntegrationResult held = integrateRotation(buffer, 0.005, 0.015, zoh);
  ASSERT_TRUE(held.ok());
  EXPECT_NEAR(logSO3(held.rotation).z(), 0.005 * 1.0 + 0.005 * 3.0, 1e-14);
  // Linear: rates 2 -> 3 -> 4 over the same interval: mean 3 rad/s.
  const IntegrationResult linear = integrateRotation(buffer, 0.005, 0.015, IntegrationOptions{});
  ASSERT_TRUE(linear.ok());
  EXPECT_NEAR(logSO3(linear.rotation).z(), 0.01 * 3.0, 1e-14);
}

TEST(IntegrateRotation, SubtractsBias) {
  const Eigen::Vector3d bias(0.01, -0.02, 0.03);
  const Eigen::Vector3d w(0.1, 0.2, 0.3);
  const ImuSampleBuffer buffer = sampledBuffer(0.0, 1.0, 200.0, [&](double) { return w + bias; });
  IntegrationOptions options;
  options.gyro_bias_rad_s = bias;
  const IntegrationResult result = integrateRotation(buffer, 0.2, 0.7, options);
  ASSERT_TRUE(result.ok());
  EXPECT_MATRIX_NEAR(expSO3(w * 0.5), result.rotation, 1e-12);
}

TEST(IntegrateRotation, ReversedIntervalGivesInverse) {
  auto rate = [](double t) { return Eigen::Vector3d(std::sin(5 * t), 0.3, std::cos(3 * t)); };
  const ImuSampleBuffer buffer = sampledBuffer(0.0, 1.0, 400.0, rate);
  const IntegrationResult forward = integrateRotation(buffer, 0.3, 0.6, IntegrationOptions{});
  const IntegrationResult backward = integrateRotation(buffer, 0.6, 0.3, IntegrationOptions{});
  ASSERT_TRUE(forward.ok() && backward.ok());
  EXPECT_MATRIX_NEAR(Eigen::Matrix3d::Identity(), forward.rotation * backward.rotation, 1e-14);
}

TEST(IntegrateRotation, ReportsCoverageProblemsWithReasons) {
  const ImuSampleBuffer buffer =
      sampledBuffer(1.0, 2.0, 100.0, [](double) { return Eigen::Vector3d(0, 0, 1); });
  const IntegrationOptions options;
  const IntegrationResult future = integrateRotation(buffer, 1.5, 2.1, options);
  EXPECT_EQ(future.status, IntegrationStatus::kNotYetAvailable);
  EXPECT_NE(future.reason.find("IMU samples end at"), std::string::npos) << future.reason;
  const IntegrationResult past = integrateRotation(buffer, 0.9, 1.5, options);
  EXPECT_EQ(past.status, IntegrationStatus::kTooOld);
  EXPECT_EQ(integrateRotation(ImuSampleBuffer(1.0), 0, 1, options).status,
            IntegrationStatus::kEmptyBuffer);
  EXPECT_EQ(integrateRotation(buffer, std::nan(""), 1.5, options).status,
            IntegrationStatus::kInvalidTime);

  ImuSampleBuffer gappy(10.0);
  for (double t : {0.0, 0.01, 0.02, 0.32, 0.33}) {
    ASSERT_TRUE(gappy.add({t, Eigen::Vector3d(0, 0, 1)}).accepted());
  }
  const IntegrationResult gap = integrateRotation(gappy, 0.005, 0.325, options);
  EXPECT_EQ(gap.status, IntegrationStatus::kGap);
  EXPECT_NE(gap.reason.find("IMU gap of 300.000 ms"), std::string::npos) << gap.reason;
  // Intervals that stay clear of the gap integrate.
  EXPECT_TRUE(integrateRotation(gappy, 0.0, 0.02, options).ok());
  EXPECT_TRUE(integrateRotation(gappy, 0.32, 0.33, options).ok());
}

}  // namespace
}  // namespace deep_ois
