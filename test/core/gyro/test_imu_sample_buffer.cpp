#include <gtest/gtest.h>

#include <limits>

#include "deep_ois/core/gyro/imu_sample_buffer.h"

namespace deep_ois {
namespace {

const Eigen::Vector3d kRate(0.1, -0.2, 0.3);

TEST(ImuSampleBuffer, KeepsSamplesInOrder) {
  ImuSampleBuffer buffer(1.0);
  EXPECT_TRUE(buffer.add({0.0, kRate}).accepted());
  EXPECT_TRUE(buffer.add({0.0025, kRate}).accepted());
  EXPECT_TRUE(buffer.add({0.0050, kRate}).accepted());
  ASSERT_EQ(buffer.size(), 3u);
  EXPECT_DOUBLE_EQ(buffer.oldestStamp(), 0.0);
  EXPECT_DOUBLE_EQ(buffer.newestStamp(), 0.005);
}

TEST(ImuSampleBuffer, RejectsNonFiniteRatesWithReason) {
  ImuSampleBuffer buffer(1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const ImuAddResult result = buffer.add({0.0, Eigen::Vector3d(nan, 0.0, 0.0)});
  EXPECT_EQ(result.status, ImuSampleStatus::kNonFiniteRate);
  EXPECT_NE(result.reason.find("non-finite angular velocity"), std::string::npos) << result.reason;
  EXPECT_TRUE(buffer.empty());
  const ImuAddResult inf = buffer.add({0.0, Eigen::Vector3d(0.0, std::numeric_limits<double>::infinity(), 0.0)});
  EXPECT_EQ(inf.status, ImuSampleStatus::kNonFiniteRate);
}

TEST(ImuSampleBuffer, RejectsNonFiniteStamp) {
  ImuSampleBuffer buffer(1.0);
  const ImuAddResult result = buffer.add({std::numeric_limits<double>::quiet_NaN(), kRate});
  EXPECT_EQ(result.status, ImuSampleStatus::kNonFiniteStamp);
  EXPECT_NE(result.reason.find("non-finite stamp"), std::string::npos) << result.reason;
}

TEST(ImuSampleBuffer, RejectsDuplicateAndOutOfOrderStamps) {
  ImuSampleBuffer buffer(1.0);
  ASSERT_TRUE(buffer.add({1.0, kRate}).accepted());
  const ImuAddResult duplicate = buffer.add({1.0, kRate});
  EXPECT_EQ(duplicate.status, ImuSampleStatus::kDuplicateStamp);
  EXPECT_NE(duplicate.reason.find("duplicate stamp"), std::string::npos) << duplicate.reason;
  const ImuAddResult reversed = buffer.add({0.99, kRate});
  EXPECT_EQ(reversed.status, ImuSampleStatus::kOutOfOrderStamp);
  EXPECT_NE(reversed.reason.find("10.000 ms older"), std::string::npos) << reversed.reason;
  EXPECT_EQ(buffer.size(), 1u);
  // A good sample after the bad ones is accepted.
  EXPECT_TRUE(buffer.add({1.0025, kRate}).accepted());
}

TEST(ImuSampleBuffer, BoundsItsDuration) {
  ImuSampleBuffer buffer(0.5);
  for (int k = 0; k <= 400; ++k) ASSERT_TRUE(buffer.add({k * 0.0025, kRate}).accepted());
  EXPECT_DOUBLE_EQ(buffer.newestStamp(), 1.0);
  EXPECT_LE(buffer.newestStamp() - buffer.oldestStamp(), 0.5 + 1e-12);
  EXPECT_GE(buffer.newestStamp() - buffer.oldestStamp(), 0.5 - 0.0025 - 1e-12);
}

TEST(ImuSampleBuffer, RefusesNonPositiveDuration) {
  EXPECT_THROW(ImuSampleBuffer(0.0), std::invalid_argument);
  EXPECT_THROW(ImuSampleBuffer(-1.0), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
