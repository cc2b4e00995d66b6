// FramePairRules: which consecutive frames pair, how long a frame waits for its IMU samples and
// the lens log, and when a pair spans lost frames (the gyro flow nodelet's rules, issue 31 item 10).
#include <gtest/gtest.h>

#include "deep_ois/core/gyro/frame_pair_rules.h"

namespace deep_ois {
namespace {

FramePairLimits limits() {
  FramePairLimits l;
  l.max_frame_interval_s = 0.25;
  l.imu_wait_timeout_s = 0.5;
  l.lens_wait_timeout_s = 0.2;
  return l;
}

TEST(FramePairRules, PairsConsecutiveFramesOfOneCamera) {
  const FramePairRules rules(limits());
  EXPECT_EQ(rules.check(10.0, 10.033, true), FramePairCheck::kPair);
  EXPECT_EQ(rules.check(10.0, 10.25, true), FramePairCheck::kPair);  // the limit itself pairs
  EXPECT_EQ(rules.check(10.0, 10.3, true), FramePairCheck::kTooFarApart);
  EXPECT_EQ(rules.check(10.0, 10.033, false), FramePairCheck::kCameraChanged);
  // Too far apart is said before a camera change.
  EXPECT_EQ(rules.check(10.0, 11.0, false), FramePairCheck::kTooFarApart);
}

TEST(FramePairRules, AFrameWaitsForItsImuWhileItMayStillCome) {
  const FramePairRules rules(limits());
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kOk, 5.0, 5.0), FrameWait::kProceed);
  // Not there yet: waits while the frame is young...
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kNotYetAvailable, 0.1, 0.1), FrameWait::kWait);
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kEmptyBuffer, 0.1, -1.0), FrameWait::kWait);
  // ...or while IMU messages still arrive (a stalled callback thread on a loaded machine)...
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kNotYetAvailable, 3.0, 0.01), FrameWait::kWait);
  // ...and gives up when both the frame waited and the IMU went quiet.
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kNotYetAvailable, 0.6, 0.6), FrameWait::kGiveUp);
  // No IMU message ever: the frame's own wait decides.
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kEmptyBuffer, 0.6, -1.0), FrameWait::kGiveUp);
  // What more data cannot fix is given up at once.
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kTooOld, 0.0, 0.0), FrameWait::kGiveUp);
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kGap, 0.0, 0.0), FrameWait::kGiveUp);
  EXPECT_EQ(rules.imuWait(IntegrationStatus::kInvalidTime, 0.0, 0.0), FrameWait::kGiveUp);
}

TEST(FramePairRules, AFrameWaitsForTheLensLogBoundedPerFrame) {
  const FramePairRules rules(limits());
  // The log ends before the pair's last row: wait while both the frame and the log are recent.
  EXPECT_EQ(rules.lensLogWait(1.00, 1.05, 0.1, 0.05), FrameWait::kWait);
  EXPECT_EQ(rules.lensLogWait(1.00, 1.05, 0.3, 0.05), FrameWait::kProceed);  // waited long enough
  EXPECT_EQ(rules.lensLogWait(1.00, 1.05, 0.1, 0.3), FrameWait::kProceed);   // the log went quiet
  // The log covers the pair: no wait.
  EXPECT_EQ(rules.lensLogWait(1.10, 1.05, 0.0, 0.0), FrameWait::kProceed);
}

TEST(FramePairRules, APairSpanningLostFramesIsCountedInTypicalIntervals) {
  FramePairRules rules(limits());
  EXPECT_EQ(rules.spannedIntervals(0.1), 0);  // no typical interval yet
  rules.accepted(1.0 / 30.0);
  rules.accepted(1.0 / 30.0);
  EXPECT_DOUBLE_EQ(rules.typicalIntervalS(), 0.0);
  rules.accepted(1.0 / 30.0);
  EXPECT_NEAR(rules.typicalIntervalS(), 1.0 / 30.0, 1e-12);
  EXPECT_EQ(rules.spannedIntervals(1.0 / 30.0), 0);
  EXPECT_EQ(rules.spannedIntervals(1.4 / 30.0), 0);
  EXPECT_EQ(rules.spannedIntervals(2.0 / 30.0), 2);
  EXPECT_EQ(rules.spannedIntervals(3.1 / 30.0), 3);
  // The median: one long interval in the history does not move it.
  rules.accepted(3.0 / 30.0);
  EXPECT_NEAR(rules.typicalIntervalS(), 1.0 / 30.0, 1e-12);
  // The history is the last nine intervals: a new frame rate takes over.
  for (int k = 0; k < 9; ++k) rules.accepted(1.0 / 60.0);
  EXPECT_NEAR(rules.typicalIntervalS(), 1.0 / 60.0, 1e-12);
  rules.clear();
  EXPECT_DOUBLE_EQ(rules.typicalIntervalS(), 0.0);
}

}  // namespace
}  // namespace deep_ois
