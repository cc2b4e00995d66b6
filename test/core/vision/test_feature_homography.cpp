// The image baselines on a synthetic pair with a known homography, and their failure mode.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>

#include "deep_ois/core/vision/feature_homography.h"

namespace deep_ois {
namespace {

// A textured grey image: random blobs of several sizes (corners and blobs for every detector).
cv::Mat texturedImage(cv::Size size, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> x(0, size.width - 1), y(0, size.height - 1), radius(2, 12),
      grey(0, 255);
  cv::Mat image(size, CV_8UC1, cv::Scalar(128));
  for (int k = 0; k < 400; ++k) {
    const int r = radius(random);
    if (k % 2) {
      cv::circle(image, {x(random), y(random)}, r, cv::Scalar(grey(random)), cv::FILLED,
                 cv::LINE_AA);
    } else {
      cv::rectangle(image, cv::Rect(x(random), y(random), 2 * r, r), cv::Scalar(grey(random)),
                    cv::FILLED);
    }
  }
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.8);
  return image;
}

// Largest distance over a grid of points between where two homographies send them, px.
double largestTransferDifference(const cv::Matx33d& a, const cv::Matx33d& b, cv::Size size) {
  double worst = 0.0;
  for (int y = 20; y < size.height - 20; y += 20) {
    for (int x = 20; x < size.width - 20; x += 20) {
      const cv::Vec3d p(x, y, 1.0), pa = a * p, pb = b * p;
      worst =
          std::max(worst, std::hypot(pa[0] / pa[2] - pb[0] / pb[2], pa[1] / pa[2] - pb[1] / pb[2]));
    }
  }
  return worst;
}

TEST(FeatureHomography, EveryDetectorAndEstimatorRecoversAKnownHomography) {
  const cv::Size size(360, 270);
  const cv::Mat a = texturedImage(size, 5);
  // A small rotation about the centre, a shift and a touch of perspective: what hand shake does.
  const cv::Matx33d truth(0.998, -0.035, 8.0, 0.035, 0.998, -3.0, 2e-5, -1e-5, 1.0);
  cv::Mat b;
  cv::warpPerspective(a, b, cv::Mat(truth), size, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  FeatureHomographyOptions options;
  for (const FeatureDetector detector :
       {FeatureDetector::kSift, FeatureDetector::kOrb, FeatureDetector::kAkaze}) {
    FeatureMatcher matcher(detector, options);
    const PointMatches matches = matcher.match({0, 1}, a, {0, 2}, b);
    EXPECT_GT(matches.points_a_px.size(), 30u) << toString(detector);
    for (const RobustEstimator estimator : {RobustEstimator::kRansac, RobustEstimator::kMagsac}) {
      const HomographyFit fit = fitHomography(matches, estimator, options);
      ASSERT_TRUE(fit.ok) << toString(detector) << " + " << toString(estimator) << ": "
                          << fit.reason;
      EXPECT_GT(fit.inliers, 20);
      EXPECT_LT(largestTransferDifference(fit.H, truth, size), 1.0)
          << toString(detector) << " + " << toString(estimator);
    }
  }
}

TEST(FeatureHomography, ABlankFrameGivesNoEstimateAndTheReasonSaysWhy) {
  const cv::Mat blank(270, 360, CV_8UC1, cv::Scalar(90));
  FeatureHomographyOptions options;
  FeatureMatcher matcher(FeatureDetector::kSift, options);
  const PointMatches matches = matcher.match({0, 1}, blank, {0, 2}, blank);
  EXPECT_EQ(matches.points_a_px.size(), 0u);
  const HomographyFit fit = fitHomography(matches, RobustEstimator::kMagsac, options);
  EXPECT_FALSE(fit.ok);
  EXPECT_EQ(fit.reason, "too few matches (< 8)");
}

TEST(FeatureHomography, FramesAreDescribedOnceAcrossConsecutivePairs) {
  // The same id means the same image: matching (1 -> 2) then (2 -> 3) with a blank image passed
  // for frame 2 the second time still uses frame 2's real features, so the match count equals the
  // one computed from the real image.
  const cv::Size size(360, 270);
  const cv::Mat f1 = texturedImage(size, 8), f2 = texturedImage(size, 8),
                f3 = texturedImage(size, 8);
  const cv::Mat blank(size, CV_8UC1, cv::Scalar(0));
  FeatureHomographyOptions options;
  FeatureMatcher cached(FeatureDetector::kOrb, options), fresh(FeatureDetector::kOrb, options);
  cached.match({0, 1}, f1, {0, 2}, f2);
  const PointMatches reused = cached.match({0, 2}, blank, {0, 3}, f3);
  const PointMatches computed = fresh.match({0, 2}, f2, {0, 3}, f3);
  EXPECT_GT(computed.points_a_px.size(), 30u);
  EXPECT_EQ(reused.points_a_px.size(), computed.points_a_px.size());
  EXPECT_EQ(reused.keypoints_a, computed.keypoints_a);
  // Another recording with the same stamp is another frame.
  const PointMatches other = cached.match({1, 2}, blank, {0, 3}, f3);
  EXPECT_EQ(other.keypoints_a, 0u);
}

TEST(FeatureHomography, OptionsAreValidated) {
  FeatureHomographyOptions options;
  options.min_matches = 3;
  EXPECT_THROW(FeatureMatcher(FeatureDetector::kSift, options), std::invalid_argument);
  options = FeatureHomographyOptions();
  options.ratio_test = 1.5;
  EXPECT_NE(options.validate(), "");
}

}  // namespace
}  // namespace deep_ois
