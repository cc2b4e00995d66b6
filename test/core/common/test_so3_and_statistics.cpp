#include <gtest/gtest.h>

#include <cmath>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

TEST(So3, SkewIsTheCrossProduct) {
  const Eigen::Vector3d v(0.3, -1.2, 2.0), w(-0.7, 0.4, 1.1);
  EXPECT_MATRIX_NEAR(v.cross(w), skew(v) * w, 1e-15);
}

TEST(So3, LogInvertsExpAndExpIsARotation) {
  for (const Eigen::Vector3d& r : {Eigen::Vector3d(1e-9, 0, 0), Eigen::Vector3d(0.01, -0.02, 0.005),
                                  Eigen::Vector3d(1.0, 0.5, -2.0)}) {
    const Eigen::Matrix3d R = expSO3(r);
    EXPECT_TRUE(isProperRotation(R));
    EXPECT_MATRIX_NEAR(r, logSO3(R), 1e-12);
  }
  EXPECT_FALSE(isProperRotation(2.0 * Eigen::Matrix3d::Identity()));
}

TEST(Statistics, MedianIsAnElementOfTheSample) {
  EXPECT_EQ(0.0, median({}));
  EXPECT_EQ(3.0, median({5.0, 3.0, 1.0}));
  // Even count: the upper of the two middle values.
  EXPECT_EQ(3.0, median({4.0, 1.0, 3.0, 2.0}));
}

}  // namespace
}  // namespace deep_ois
