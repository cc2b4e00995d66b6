// DelayedCalibrationFeed's contract with the estimator it feeds (the real one): a pair is held
// until later pairs' gyro covers it by coverageFor(options), then added; order is kept; nothing is
// dropped uncounted; a gap forward releases what the gyro now covers; time going back (cleared by
// the caller or not) starts a timeline the estimator takes again.
#include <gtest/gtest.h>

#include <vector>

#include "deep_ois/core/online/online_calibration_delayed_feed.h"
#include "deep_ois/core/online/online_calibration_estimator.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"

namespace deep_ois {
namespace {

constexpr double kFramePeriodS = 1.0 / 30.0;
constexpr double kGyroPeriodS = 1.0 / 200.0;

CameraModel camera() {
  Eigen::Matrix3d K;
  K << 300.0, 0.0, 180.0, 0.0, 300.0, 135.0, 0.0, 0.0, 1.0;
  return CameraModel(360, 270, K);
}

OnlineCalibrationOptions options() {
  OnlineCalibrationOptions o;
  o.cpu_share = 0.0;  // no budget: the same work on every run
  return o;
}

// The pair (frame a at stamp_a_s) as the gyro flow sends it: its camera-frame gyro from the
// warm-up before frame a up to frame b, no further. Untracked (no matches): it still adds time.
OnlineFramePair pairAt(double stamp_a_s) {
  OnlineFramePair pair;
  pair.stamp_a_s = stamp_a_s;
  pair.stamp_b_s = stamp_a_s + kFramePeriodS;
  pair.camera = camera();
  for (double t = stamp_a_s - 0.1; t <= pair.stamp_b_s + 1e-9; t += kGyroPeriodS)
    pair.rates.push_back({t, Eigen::Vector3d(0.1, -0.2, 0.05)});
  return pair;
}

double gyroEnd(const OnlineFramePair& pair) { return pair.rates.back().stamp_s; }

struct Fixture {
  OnlineCalibrationEstimator estimator{options(), camera(), CameraImuCalibration()};
  DelayedCalibrationFeed feed{DelayedCalibrationFeed::coverageFor(options())};
  std::vector<double> added_b_s;  // frame b of every pair added, in the order added
  std::size_t fed = 0;

  std::vector<OnlineCalibrationPair> feedPair(const OnlineFramePair& pair) {
    ++fed;
    bool changed = true;
    std::vector<OnlineCalibrationPair> added = feed.feed(pair, estimator, &changed);
    EXPECT_FALSE(changed);  // no tracks: the calibration in use stays
    for (const OnlineCalibrationPair& a : added) added_b_s.push_back(a.stamp_b_s);
    return added;
  }
};

TEST(DelayedCalibrationFeed, HoldsEachPairUntilLaterGyroCoversIt) {
  Fixture f;
  const double coverage_s = DelayedCalibrationFeed::coverageFor(options());
  ASSERT_GT(coverage_s, options().first_search_s);  // any offset the coarse search may find
  std::vector<double> fed_b_s;
  for (int k = 0; k < 40; ++k) {
    const OnlineFramePair pair = pairAt(10.0 + k * kFramePeriodS);
    fed_b_s.push_back(pair.stamp_b_s);
    f.feedPair(pair);
    // Added: exactly the pairs the gyro covers by coverage_s (offset 0), in order.
    std::size_t covered = 0;
    for (double b : fed_b_s)
      if (b + coverage_s <= gyroEnd(pair)) ++covered;
    ASSERT_EQ(f.added_b_s.size(), covered) << "after pair " << k;
    EXPECT_EQ(f.feed.waiting(), fed_b_s.size() - covered);
    EXPECT_EQ(f.estimator.status().pairs, covered);
  }
  // 0.16 s at 30 fps: the newest 5 wait (a pair's own gyro never covers it).
  EXPECT_EQ(f.feed.waiting(), 5u);
  EXPECT_EQ(std::vector<double>(fed_b_s.begin(), fed_b_s.end() - 5), f.added_b_s);
  EXPECT_EQ(f.feed.dropped(), 0u);
}

TEST(DelayedCalibrationFeed, WaitsLongerWhenTheImuIsLate) {
  // The coverage is on the IMU clock: camera stamp + the estimate's offset.
  CameraImuCalibration start;
  start.time_offset_s = 0.1;  // IMU stamps 0.1 s later than the camera's
  OnlineCalibrationEstimator estimator(options(), camera(), start);
  DelayedCalibrationFeed feed(DelayedCalibrationFeed::coverageFor(options()));
  const double coverage_s = DelayedCalibrationFeed::coverageFor(options());
  std::vector<double> fed_b_s;
  std::size_t added = 0;
  for (int k = 0; k < 40; ++k) {
    OnlineFramePair pair = pairAt(10.0 + k * kFramePeriodS);
    for (CameraRateSample& r : pair.rates) r.stamp_s += start.time_offset_s;
    fed_b_s.push_back(pair.stamp_b_s);
    added += feed.feed(pair, estimator, nullptr).size();
    std::size_t covered = 0;
    for (double b : fed_b_s)
      if (b + start.time_offset_s + coverage_s <= gyroEnd(pair)) ++covered;
    ASSERT_EQ(added, covered) << "after pair " << k;
  }
  EXPECT_EQ(feed.waiting(), 5u);  // as with no offset: the gyro's stamps are later by as much
}

TEST(DelayedCalibrationFeed, AGapForwardReleasesWhatTheGyroCoversInOrder) {
  Fixture f;
  for (int k = 0; k < 10; ++k) f.feedPair(pairAt(10.0 + k * kFramePeriodS));
  const std::size_t waiting = f.feed.waiting();
  ASSERT_GT(waiting, 0u);
  const std::size_t before = f.added_b_s.size();
  // The camera stalls 2 s: the next pair's gyro covers every waiting one.
  const std::vector<OnlineCalibrationPair> added = f.feedPair(pairAt(12.5));
  ASSERT_EQ(added.size(), waiting);
  for (std::size_t i = 1; i < f.added_b_s.size(); ++i) EXPECT_LT(f.added_b_s[i - 1], f.added_b_s[i]);
  EXPECT_EQ(f.added_b_s.size(), before + waiting);
  EXPECT_EQ(f.feed.waiting(), 1u);  // the new pair, for later gyro
  EXPECT_EQ(f.feed.dropped(), 0u);
  EXPECT_EQ(f.estimator.status().pairs, f.added_b_s.size());
}

// Every pair is added, waiting or counted as dropped.
void expectAccounted(const Fixture& f) {
  EXPECT_EQ(f.added_b_s.size() + f.feed.waiting() + f.feed.dropped(), f.fed);
}

TEST(DelayedCalibrationFeed, ClearedTimeStartsOverAndCountsWhatItDrops) {
  // As the nodelet does when time goes back: the estimator's timeline restarted, the feed cleared.
  Fixture f;
  for (int k = 0; k < 20; ++k) f.feedPair(pairAt(100.0 + k * kFramePeriodS));
  const std::size_t waiting = f.feed.waiting();
  ASSERT_GT(waiting, 0u);
  f.estimator.restartTimeline();
  f.feed.clear();
  EXPECT_EQ(f.feed.dropped(), waiting);
  EXPECT_EQ(f.feed.waiting(), 0u);
  expectAccounted(f);
  // The new timeline's first pair is not covered by the old timeline's (later) gyro: it waits.
  const std::size_t pairs_before = f.estimator.status().pairs;
  EXPECT_TRUE(f.feedPair(pairAt(10.0)).empty());
  for (int k = 1; k < 20; ++k) f.feedPair(pairAt(10.0 + k * kFramePeriodS));
  EXPECT_EQ(f.feed.waiting(), 5u);
  // ...and the estimator takes them (it would ignore pairs older than its last otherwise).
  EXPECT_EQ(f.estimator.status().pairs, pairs_before + 15u);
  expectAccounted(f);
}

TEST(DelayedCalibrationFeed, TimeGoingBackUnclearedRestartsTheEstimatorsTimeline) {
  Fixture f;
  for (int k = 0; k < 20; ++k) f.feedPair(pairAt(100.0 + k * kFramePeriodS));
  const std::size_t waiting = f.feed.waiting();
  const std::size_t pairs_before = f.estimator.status().pairs;
  // A replay loops, nobody says so: the queued pairs are counted as dropped.
  EXPECT_TRUE(f.feedPair(pairAt(10.0)).empty());
  EXPECT_EQ(f.feed.dropped(), waiting);
  EXPECT_EQ(f.feed.waiting(), 1u);
  for (int k = 1; k < 20; ++k) f.feedPair(pairAt(10.0 + k * kFramePeriodS));
  EXPECT_EQ(f.feed.waiting(), 5u);
  EXPECT_EQ(f.estimator.status().pairs, pairs_before + 15u);
  // In order within each timeline: back once, at the loop.
  int backs = 0;
  for (std::size_t i = 1; i < f.added_b_s.size(); ++i) backs += f.added_b_s[i] < f.added_b_s[i - 1];
  EXPECT_EQ(backs, 1);
  expectAccounted(f);
}

TEST(DelayedCalibrationFeed, ARepeatedPairIsCountedNotAddedTwice) {
  Fixture f;
  for (int k = 0; k < 20; ++k) {
    const OnlineFramePair pair = pairAt(10.0 + k * kFramePeriodS);
    f.feedPair(pair);
    if (k == 3) f.feedPair(pair);
  }
  EXPECT_EQ(f.feed.dropped(), 1u);
  EXPECT_EQ(f.feed.repeats(), 1u);
  EXPECT_EQ(f.feed.waiting(), 5u);
  EXPECT_EQ(f.added_b_s.size(), 15u);
  for (std::size_t i = 1; i < f.added_b_s.size(); ++i) EXPECT_LT(f.added_b_s[i - 1], f.added_b_s[i]);
  expectAccounted(f);
}

}  // namespace
}  // namespace deep_ois
