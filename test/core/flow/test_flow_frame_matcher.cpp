#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "deep_ois/core/flow/flow_frame_matcher.h"

namespace deep_ois {
namespace {

constexpr std::int64_t kFrameNs = 33333333;  // 30 fps
using Matcher = FlowFrameMatcher<int, int>;   // flow id, frame index

std::int64_t stamp(int frame) { return static_cast<std::int64_t>(frame) * kFrameNs; }

// Feeds frames 0..n-1 and the flows i-1 -> i, the flow of each pair right after its frame b,
// skipping the frames in `missing`; returns the settled flows in order.
std::vector<Matcher::Settled> run(Matcher& matcher, int n, const std::vector<int>& missing) {
  std::vector<Matcher::Settled> all;
  auto append = [&all](std::vector<Matcher::Settled> s) { all.insert(all.end(), s.begin(), s.end()); };
  for (int i = 0; i < n; ++i) {
    const double now_s = i / 30.0;
    if (std::find(missing.begin(), missing.end(), i) == missing.end()) append(matcher.addFrame(stamp(i), i, now_s));
    if (i > 0) append(matcher.addFlow(stamp(i - 1), stamp(i), i, now_s));
  }
  return all;
}

TEST(FlowFrameMatcher, PairsEveryFlowWithItsFrames) {
  Matcher matcher({});
  const auto settled = run(matcher, 10, {});
  ASSERT_EQ(settled.size(), 9u);
  for (std::size_t k = 0; k < settled.size(); ++k) {
    EXPECT_TRUE(settled[k].matched);
    EXPECT_EQ(settled[k].flow, static_cast<int>(k) + 1);
    EXPECT_EQ(settled[k].frame_a, static_cast<int>(k));
    EXPECT_EQ(settled[k].frame_b, static_cast<int>(k) + 1);
  }
  EXPECT_EQ(matcher.pendingFlows(), 0u);
}

// Defect 1 of issue 14: one missing frame stopped the compensation for good. Here it costs only
// the two flows that need it, dropped as soon as a newer frame shows it will not come; every
// later flow is matched at once.
TEST(FlowFrameMatcher, AMissingFrameCostsOnlyTheFlowsThatNeedIt) {
  Matcher matcher({});
  const auto settled = run(matcher, 300, {100});
  ASSERT_EQ(settled.size(), 299u);
  int dropped = 0;
  for (const auto& s : settled) {
    if (s.flow == 100 || s.flow == 101) {
      EXPECT_FALSE(s.matched) << s.flow;
      EXPECT_EQ(s.reason, FlowDropReason::kFrameNeverCame);
      ++dropped;
    } else {
      EXPECT_TRUE(s.matched) << s.flow;
    }
  }
  EXPECT_EQ(dropped, 2);
  EXPECT_EQ(matcher.pendingFlows(), 0u);
}

TEST(FlowFrameMatcher, AnOrphanFlowDoesNotDelayTheOthers) {
  Matcher matcher({});
  for (int i = 0; i < 5; ++i) matcher.addFrame(stamp(i), i, 0.0);
  // A flow whose frames are newer than every frame: it may still be matched, it waits.
  EXPECT_TRUE(matcher.addFlow(stamp(7) + 5, stamp(8) + 5, 99, 0.0).empty());
  // Flows behind it are matched at once.
  const auto s = matcher.addFlow(stamp(3), stamp(4), 4, 0.0);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_TRUE(s[0].matched);
  // Frame 9 shows the orphan's frames will never come.
  const auto later = matcher.addFrame(stamp(9), 9, 0.1);
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].flow, 99);
  EXPECT_FALSE(later[0].matched);
  EXPECT_EQ(later[0].reason, FlowDropReason::kFrameNeverCame);
}

TEST(FlowFrameMatcher, FlowsArrivingBeforeTheirFramesWait) {
  Matcher matcher({});
  matcher.addFrame(stamp(0), 0, 0.0);
  EXPECT_TRUE(matcher.addFlow(stamp(0), stamp(1), 1, 0.0).empty());
  EXPECT_TRUE(matcher.addFlow(stamp(1), stamp(2), 2, 0.0).empty());
  const auto s1 = matcher.addFrame(stamp(1), 1, 0.01);
  ASSERT_EQ(s1.size(), 1u);
  EXPECT_EQ(s1[0].flow, 1);
  const auto s2 = matcher.addFrame(stamp(2), 2, 0.02);
  ASSERT_EQ(s2.size(), 1u);
  EXPECT_EQ(s2[0].flow, 2);
}

TEST(FlowFrameMatcher, AFrameThatNeverComesIsGivenUpAfterMaxWait) {
  FlowFrameMatcherOptions options;
  options.max_wait_s = 0.5;
  Matcher matcher(options);
  matcher.addFrame(stamp(0), 0, 0.0);
  EXPECT_TRUE(matcher.addFlow(stamp(0), stamp(1), 1, 0.0).empty());
  EXPECT_TRUE(matcher.expire(0.4).empty());
  const auto s = matcher.expire(0.6);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].reason, FlowDropReason::kWaitedTooLong);
}

TEST(FlowFrameMatcher, AFlowOlderThanTheCacheIsDroppedAtOnce) {
  FlowFrameMatcherOptions options;
  options.frame_cache_size = 4;
  Matcher matcher(options);
  for (int i = 0; i < 10; ++i) matcher.addFrame(stamp(i), i, 0.0);
  const auto s = matcher.addFlow(stamp(2), stamp(3), 3, 0.0);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].reason, FlowDropReason::kFrameLeftCache);
  EXPECT_TRUE(matcher.addFlow(stamp(8), stamp(9), 9, 0.0)[0].matched);
}

TEST(FlowFrameMatcher, PendingFlowsAreBounded) {
  FlowFrameMatcherOptions options;
  options.max_pending_flows = 3;
  Matcher matcher(options);
  matcher.addFrame(stamp(0), 0, 0.0);
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(matcher.addFlow(stamp(i), stamp(i + 1), i, 0.0).empty());
  const auto s = matcher.addFlow(stamp(4), stamp(5), 4, 0.0);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].flow, 1);
  EXPECT_EQ(s[0].reason, FlowDropReason::kTooManyPending);
  EXPECT_EQ(matcher.pendingFlows(), 3u);
}

TEST(FlowFrameMatcher, ABagLoopRestartsTheCacheAndMatchesTheNewRun) {
  Matcher matcher({});
  run(matcher, 20, {});
  // Frames of the next run start at 0 again; a flow of the old run still waiting is dropped.
  EXPECT_TRUE(matcher.addFlow(stamp(20), stamp(21), 21, 1.0).empty());
  const auto s = matcher.addFrame(stamp(0), 0, 1.0);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].reason, FlowDropReason::kTimeJumpedBack);
  matcher.addFrame(stamp(1), 1, 1.0);
  const auto m = matcher.addFlow(stamp(0), stamp(1), 1, 1.0);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_TRUE(m[0].matched);
}

TEST(FlowFrameMatcher, DuplicateFramesAreIgnored) {
  Matcher matcher({});
  matcher.addFrame(stamp(0), 0, 0.0);
  matcher.addFrame(stamp(1), 1, 0.0);
  EXPECT_TRUE(matcher.addFrame(stamp(1), 1, 0.0).empty());
  EXPECT_EQ(matcher.cachedFrames(), 2u);
  EXPECT_TRUE(matcher.addFlow(stamp(0), stamp(1), 1, 0.0)[0].matched);
}

}  // namespace
}  // namespace deep_ois
