// The annotation proposer on a synthetic pair with a known sub-pixel motion: every candidate must
// land on it, and the checks must reject what cannot be matched.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "deep_ois/tools/support/correspondence_proposer.h"

namespace deep_ois {
namespace {

// Blurred random blocks: corners everywhere, no repetition.
cv::Mat texture(int width, int height) {
  cv::Mat image(height, width, CV_8UC1);
  cv::RNG rng(7);
  for (int y = 0; y < height; y += 6)
    for (int x = 0; x < width; x += 6)
      image(cv::Rect(x, y, std::min(6, width - x), std::min(6, height - y))).setTo(rng.uniform(0, 256));
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.2);
  return image;
}

cv::Mat shifted(const cv::Mat& image, double dx, double dy) {
  const cv::Mat M = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, dy);
  cv::Mat out;
  cv::warpAffine(image, out, M, image.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  return out;
}

TEST(CorrespondenceProposer, FindsAKnownSubPixelShift) {
  const cv::Mat a = texture(320, 240);
  const cv::Mat b = shifted(a, 1.37, -0.62);
  const auto candidates = proposeCorrespondences(a, b, cv::Rect(40, 40, 240, 160), {});
  ASSERT_EQ(candidates.size(), 12u);
  for (const CorrespondenceCandidate& c : candidates) {
    EXPECT_TRUE(cv::Rect(40, 40, 240, 160).contains(cv::Point(c.point_a_px)));
    EXPECT_NEAR(c.point_b_px.x - c.point_a_px.x, 1.37, 0.05) << "candidate " << c.id;
    EXPECT_NEAR(c.point_b_px.y - c.point_a_px.y, -0.62, 0.05) << "candidate " << c.id;
    EXPECT_LE(c.disagreement_px, 0.3);
    EXPECT_GE(c.zncc, 0.95);
    EXPECT_LE(c.forward_backward_error_px, 0.1);
  }
  for (std::size_t i = 1; i < candidates.size(); ++i) {
    EXPECT_EQ(candidates[i].id, static_cast<int>(i));
    EXPECT_GE(candidates[i - 1].corner_strength, candidates[i].corner_strength);
    for (std::size_t j = 0; j < i; ++j) {
      // Detected >= 25 px apart, then each refined by at most 4 px per axis.
      EXPECT_GE(cv::norm(candidates[i].point_a_px - candidates[j].point_a_px), 25.0 - 2.0 * std::hypot(4.0, 4.0));
    }
  }
}

TEST(CorrespondenceProposer, RejectsWhatDoesNotMatch) {
  const cv::Mat a = texture(320, 240);
  // Frame b is unrelated texture: nothing may pass the forward-backward, agreement and ZNCC checks.
  cv::Mat b = texture(320, 240);
  cv::flip(b, b, -1);
  EXPECT_TRUE(proposeCorrespondences(a, b, cv::Rect(40, 40, 240, 160), {}).empty());
  // A flat region has no corners.
  const cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(90));
  EXPECT_TRUE(proposeCorrespondences(flat, flat, cv::Rect(0, 0, 320, 240), {}).empty());
}

TEST(CorrespondenceProposer, BadInputIsNamed) {
  const cv::Mat a = texture(320, 240);
  CorrespondenceProposerOptions options;
  options.zoom = 0;
  EXPECT_NE(options.validate().find("zoom"), std::string::npos);
  EXPECT_THROW(proposeCorrespondences(a, a, cv::Rect(0, 0, 10, 10), options), std::invalid_argument);
  EXPECT_THROW(proposeCorrespondences(a, a, cv::Rect(400, 300, 10, 10), {}), std::invalid_argument);
  cv::Mat colour;
  cv::cvtColor(a, colour, cv::COLOR_GRAY2RGB);
  EXPECT_THROW(proposeCorrespondences(colour, colour, cv::Rect(0, 0, 100, 100), {}), std::invalid_argument);
}

TEST(CorrespondenceProposer, CropsAndOverview) {
  const cv::Mat a = texture(320, 240);
  cv::Mat rgb;
  cv::cvtColor(a, rgb, cv::COLOR_GRAY2RGB);
  CorrespondenceCandidate c;
  c.point_a_px = {5.3, 7.8};  // near the corner: the crop pads instead of failing
  c.point_b_px = {160.2, 120.9};
  const cv::Mat crop = renderCandidateCrop(rgb, rgb, c, 12, 8);
  EXPECT_EQ(crop.rows, 25 * 8);
  EXPECT_EQ(crop.cols, 2 * 25 * 8 + 6);
  EXPECT_EQ(crop.type(), CV_8UC3);
  const cv::Mat overview = renderCandidateOverview(rgb, cv::Rect(10, 10, 100, 80), {c});
  EXPECT_EQ(overview.size(), rgb.size());
  EXPECT_GT(cv::norm(overview, rgb, cv::NORM_L1), 0.0);  // something was drawn
}

}  // namespace
}  // namespace deep_ois
