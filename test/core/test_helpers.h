// Assertions and builders shared by the core gtests.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <sstream>

#include "deep_ois/core/gyro/imu_sample_buffer.h"

namespace deep_ois {
namespace test {

// Passes when every entry of `actual` is within `tolerance` of `expected`.
template <typename A, typename B>
::testing::AssertionResult matricesNear(const Eigen::MatrixBase<A>& expected,
                                        const Eigen::MatrixBase<B>& actual, double tolerance) {
  if (expected.rows() != actual.rows() || expected.cols() != actual.cols()) {
    return ::testing::AssertionFailure() << "size differs";
  }
  const double worst = (expected - actual).cwiseAbs().maxCoeff();
  if (worst <= tolerance) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "largest difference " << worst << " > " << tolerance
                                       << "\nexpected:\n"
                                       << expected << "\nactual:\n"
                                       << actual;
}

#define EXPECT_MATRIX_NEAR(expected, actual, tolerance) \
  EXPECT_TRUE(::deep_ois::test::matricesNear((expected), (actual), (tolerance)))

// Applies a homography to a pixel.
inline Eigen::Vector2d applyHomography(const Eigen::Matrix3d& H, const Eigen::Vector2d& p) {
  return (H * p.homogeneous()).hnormalized();
}

// A buffer sampled at `rate_hz` over [t0_s, t1_s] from an angular velocity function of time.
template <typename RateFunction>
ImuSampleBuffer sampledBuffer(double t0_s, double t1_s, double rate_hz, RateFunction rate) {
  ImuSampleBuffer buffer(t1_s - t0_s + 1.0);
  const int count = static_cast<int>(std::round((t1_s - t0_s) * rate_hz));
  for (int k = 0; k <= count; ++k) {
    const double t = t0_s + k / rate_hz;
    EXPECT_TRUE(buffer.add({t, rate(t)}).accepted());
  }
  return buffer;
}

inline Eigen::Matrix3d phoneLikeK() {
  Eigen::Matrix3d K;
  K << 300.0, 0.0, 179.5, 0.0, 300.0, 134.5, 0.0, 0.0, 1.0;
  return K;
}

}  // namespace test
}  // namespace deep_ois
