#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "deep_ois/core/flow/motion_history.h"

namespace deep_ois {
namespace {

constexpr std::int64_t kFrameNs = 33333333;  // 30 fps

cv::Mat uniformFlow(cv::Size grid, float u, float v) { return cv::Mat(grid, CV_32FC2, cv::Scalar(u, v)); }

float channelAt(const cv::Mat& flow, int channel) { return flow.at<cv::Vec2f>(flow.rows / 2, flow.cols / 2)[channel]; }

TEST(MotionHistory, LeakySumsDecayWithTheirOwnTimeConstants) {
  const cv::Size grid(6, 4);
  MotionHistory history({0.1, 1.0}, grid);
  // Frame pairs 0->1, 1->2, 2->3 with flows (1, 0), (0, 2), (3, 0).
  const std::vector<cv::Mat> flows = {uniformFlow(grid, 1, 0), uniformFlow(grid, 0, 2), uniformFlow(grid, 3, 0)};
  for (std::size_t i = 0; i < flows.size(); ++i) {
    const std::int64_t a = static_cast<std::int64_t>(i) * kFrameNs;
    const std::vector<cv::Mat>& before = history.before(a);
    if (i == 0) {
      EXPECT_EQ(channelAt(before[0], 0), 0.0f);
    }
    history.add(a, a + kFrameNs, flows[i]);
  }
  const std::vector<cv::Mat>& sums = history.before(3 * kFrameNs);
  ASSERT_EQ(sums.size(), 2u);
  const double dt = 1e-9 * kFrameNs;
  for (int k = 0; k < 2; ++k) {
    const double d = std::exp(-dt / (k == 0 ? 0.1 : 1.0));
    EXPECT_NEAR(channelAt(sums[k], 0), 1.0 * d * d + 3.0, 1e-5) << "time constant " << k;
    EXPECT_NEAR(channelAt(sums[k], 1), 2.0 * d, 1e-5) << "time constant " << k;
  }
  EXPECT_EQ(history.pairsSinceReset(), 3u);
}

TEST(MotionHistory, RestartsWhenThePairsDoNotChain) {
  const cv::Size grid(5, 5);
  MotionHistory history({0.2}, grid);
  history.before(0);
  history.add(0, kFrameNs, uniformFlow(grid, 2, 2));
  EXPECT_GT(channelAt(history.before(kFrameNs)[0], 0), 1.0f);  // chained: the sum is kept
  // A dropped frame: the next pair starts at frame 2, not at frame 1 where the last one ended.
  EXPECT_EQ(channelAt(history.before(2 * kFrameNs)[0], 0), 0.0f);
  EXPECT_EQ(history.pairsSinceReset(), 0u);
  history.add(2 * kFrameNs, 3 * kFrameNs, uniformFlow(grid, 1, 0));
  // A bag that loops: time goes back.
  EXPECT_EQ(channelAt(history.before(0)[0], 0), 0.0f);
}

TEST(MotionHistory, NoTimeConstantsMeansNoChannels) {
  MotionHistory history({}, cv::Size(3, 3));
  EXPECT_TRUE(history.before(0).empty());
  history.add(0, kFrameNs, uniformFlow(cv::Size(3, 3), 1, 1));
  EXPECT_TRUE(history.before(kFrameNs).empty());
}

TEST(MotionHistory, RejectsBadInput) {
  EXPECT_THROW(MotionHistory({0.0}, cv::Size(3, 3)), std::invalid_argument);
  EXPECT_THROW(MotionHistory({NAN}, cv::Size(3, 3)), std::invalid_argument);
  EXPECT_THROW(MotionHistory({0.1}, cv::Size(0, 3)), std::invalid_argument);
  MotionHistory history({0.1}, cv::Size(4, 3));
  EXPECT_THROW(history.add(0, kFrameNs, uniformFlow(cv::Size(3, 4), 1, 1)), std::invalid_argument);
  EXPECT_THROW(history.add(0, kFrameNs, cv::Mat::zeros(3, 4, CV_64FC2)), std::invalid_argument);
  EXPECT_THROW(history.add(kFrameNs, kFrameNs, uniformFlow(cv::Size(4, 3), 1, 1)), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
