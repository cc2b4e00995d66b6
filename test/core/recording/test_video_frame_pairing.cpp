// The frame-to-metadata pairing check (core/recording/video_frame_pairing): synthetic image motion
// that follows the gyro one frame late is paired with that shift, confidently; motion unrelated to
// the gyro is not confidently paired; timed presentation times choose the shift themselves.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "deep_ois/core/recording/video_frame_pairing.h"

namespace deep_ois {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A gyro series of 300 rows (bursts of shake over a still phone) and video frames j = row j - 1
// whose image motion is a rotated, scaled copy of it plus tracking noise; frame 0 has no motion.
struct Series {
  std::vector<double> rows_s, presentation_s;
  std::vector<Eigen::Vector2d> gyro, image;
};

Series makeSeries(bool related, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0.0, 0.3);
  Series s;
  for (int r = 0; r < 300; ++r) {
    s.rows_s.push_back(100.0 + r / 30.0);
    const double burst = (r / 40) % 2 == 1 ? 6.0 : 0.3;
    s.gyro.push_back(r == 0 ? Eigen::Vector2d(kNaN, kNaN)
                            : Eigen::Vector2d(burst * std::sin(0.7 * r), burst * std::cos(0.45 * r)));
  }
  for (int j = 0; j < 301; ++j) {
    s.presentation_s.push_back(j / 30.0);  // uniform: no timing
    const int r = j - 1;
    if (j == 0 || r < 1) {
      s.image.push_back(Eigen::Vector2d(kNaN, kNaN));
      continue;
    }
    const Eigen::Vector2d g = related ? s.gyro[static_cast<std::size_t>(r)]
                                      : Eigen::Vector2d(6.0 * std::sin(1.3 * j), 6.0 * std::cos(0.9 * j));
    // Another axis convention: image x = -gyro y, image y = gyro x (a quarter turn), and noise.
    s.image.push_back(Eigen::Vector2d(-g.y() + noise(random), g.x() + noise(random)));
  }
  return s;
}

TEST(VideoFramePairing, ImageMotionOneFrameLateIsPairedWithShiftOneConfidently) {
  const Series s = makeSeries(true, 1);
  const VideoFramePairing pairing = pairVideoFrames(s.presentation_s, s.image, s.rows_s, s.gyro);
  EXPECT_EQ(pairing.shift, 1) << pairing.summary();
  EXPECT_TRUE(pairing.confident) << pairing.summary();
  EXPECT_FALSE(pairing.by_presentation_time);
  EXPECT_GT(pairing.correlation, 0.9);
  EXPECT_EQ(pairing.video_frames_without_row, 1);  // frame 0
  EXPECT_EQ(pairing.rows_without_frame, 0);
  EXPECT_NE(pairing.summary().find("a shift of 1 whole frame"), std::string::npos) << pairing.summary();
}

TEST(VideoFramePairing, MotionUnrelatedToTheGyroIsNotConfident) {
  const Series s = makeSeries(false, 2);
  const VideoFramePairing pairing = pairVideoFrames(s.presentation_s, s.image, s.rows_s, s.gyro);
  EXPECT_FALSE(pairing.confident) << pairing.summary();
  EXPECT_NE(pairing.summary().find("confidence LOW"), std::string::npos);
}

TEST(VideoFramePairing, TimedPresentationTimesChooseTheShift) {
  Series s = makeSeries(true, 3);
  // Rows with jittered intervals (a phone's frame times); presentation times carry them, shifted
  // by the one frame the video has before the first row.
  std::mt19937 random(4);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  for (std::size_t r = 1; r < s.rows_s.size(); ++r) s.rows_s[r] = s.rows_s[r - 1] + 1.0 / 30.0 + jitter(random);
  for (std::size_t j = 1; j < s.presentation_s.size(); ++j)
    s.presentation_s[j] = s.rows_s[std::min(j - 1, s.rows_s.size() - 1)] - s.rows_s[0] + 0.0333;
  const VideoFramePairing pairing = pairVideoFrames(s.presentation_s, s.image, s.rows_s, s.gyro);
  EXPECT_TRUE(pairing.by_presentation_time) << pairing.summary();
  EXPECT_EQ(pairing.shift, 1) << pairing.summary();
  EXPECT_TRUE(pairing.confident) << pairing.summary();
}

}  // namespace
}  // namespace deep_ois
