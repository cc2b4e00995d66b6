// StampClockCheck: stamps far from ROS time are said once per timeline (issue 31, item 3).
#include <gtest/gtest.h>

#include "deep_ois/core/common/stamp_clock_check.h"

namespace deep_ois {
namespace {

constexpr double kWallNowS = 1.79e9;      // 2026 on the wall clock
constexpr double kBagStampS = 1.2e9;      // 2008: a recording's stamps
constexpr double kYearS = 365.25 * 86400.0;

TEST(StampClockCheck, StampsNearTheClockAgree) {
  StampClockCheck check;
  for (int k = 0; k < 100; ++k) {
    // Latencies up to 30 s (a stalled pipeline) are not a clock mix-up.
    EXPECT_FALSE(check.observe(kWallNowS + 0.03 * k - 30.0, kWallNowS + 0.03 * k));
    EXPECT_FALSE(check.disagrees());
  }
  EXPECT_TRUE(check.describe().empty());
}

TEST(StampClockCheck, BagStampsOnTheWallClockAreSaidOnceNamingUseSimTime) {
  StampClockCheck check;
  int said = 0;
  for (int k = 0; k < 300; ++k) said += check.observe(kBagStampS + 0.01 * k, kWallNowS + 0.01 * k);
  EXPECT_EQ(said, 1);
  EXPECT_TRUE(check.disagrees());
  EXPECT_NEAR(check.offsetS(), kBagStampS - kWallNowS, 1e-3);
  const std::string text = check.describe();
  EXPECT_NE(text.find("behind ROS time"), std::string::npos) << text;
  EXPECT_NE(text.find("use_sim_time:=true"), std::string::npos) << text;
  EXPECT_NE(text.find("18.7 years"), std::string::npos) << text;
}

TEST(StampClockCheck, WallStampsUnderSimulatedTimeAreSaidTheOtherWayRound) {
  StampClockCheck check;
  EXPECT_TRUE(check.observe(kWallNowS, 1000.0));  // a simulator's /clock from 0
  const std::string text = check.describe();
  EXPECT_NE(text.find("ahead of ROS time"), std::string::npos) << text;
  EXPECT_NE(text.find("use_sim_time"), std::string::npos) << text;
}

TEST(StampClockCheck, AClockAtZeroDecidesNothing) {
  // use_sim_time before the first /clock message: ros::Time::now() is 0.
  StampClockCheck check;
  EXPECT_FALSE(check.observe(kWallNowS, 0.0));
  EXPECT_FALSE(check.disagrees());
}

TEST(StampClockCheck, SaysAgainAfterRosTimeWentBackOnly) {
  StampClockCheck check;
  int said = 0;
  for (int k = 0; k < 100; ++k) said += check.observe(kBagStampS + 0.1 * k, kWallNowS + 0.1 * k);
  EXPECT_EQ(said, 1);
  // Stamps agreeing for a while, then disagreeing again on the same timeline: not said again.
  for (int k = 0; k < 10; ++k) said += check.observe(kWallNowS + 10.0 + k, kWallNowS + 10.0 + k);
  EXPECT_FALSE(check.disagrees());
  said += check.observe(kBagStampS + 1e6, kWallNowS + 30.0);
  EXPECT_EQ(said, 1);
  // The bag loops while use_sim_time is false (stamps go back, the clock does not): the same
  // mistake, already said; so are messages of two inputs crossing (old and new stamps in turn).
  for (int k = 0; k < 100; ++k) said += check.observe(kBagStampS + 0.1 * k, kWallNowS + 40.0 + 0.1 * k);
  for (int k = 0; k < 10; ++k) said += check.observe(k % 2 ? kBagStampS : kWallNowS + 50.0, kWallNowS + 50.0);
  EXPECT_EQ(said, 1);
  // ROS time goes back (a bag looping under use_sim_time, a restarted simulator): said once more.
  for (int k = 0; k < 100; ++k) said += check.observe(kWallNowS + 0.1 * k, 1000.0 + 0.1 * k);
  EXPECT_EQ(said, 2);
}

TEST(StampClockCheck, ReadableDurations) {
  EXPECT_EQ(readableDuration(42.0), "42.0 s");
  EXPECT_EQ(readableDuration(600.0), "10.0 min");
  EXPECT_EQ(readableDuration(3.5 * 3600.0), "3.5 h");
  EXPECT_EQ(readableDuration(12.0 * 86400.0), "12.0 days");
  EXPECT_EQ(readableDuration(56.9 * kYearS), "56.9 years");
}

}  // namespace
}  // namespace deep_ois
