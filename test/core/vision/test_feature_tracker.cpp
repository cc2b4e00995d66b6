#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <random>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {
namespace {

// A random field of Gaussian blobs, rendered analytically at (x - shift_x, y - shift_y). The
// texture is a function of continuous position, so a sub-pixel shift is exact rather than an
// interpolation of the unshifted image.
struct Blob {
  double x, y, sigma, amplitude;
};

// Fine blobs give corners; coarse ones give the large-scale structure natural images have, without
// which the coarse pyramid levels see only mush and KLT cannot follow large motions.
std::vector<Blob> randomBlobs(cv::Size size, unsigned seed) {
  std::mt19937 rng(seed);
  // Blobs also fall a little outside the image so the texture is uniform up to its edges.
  std::uniform_real_distribution<double> x(-30.0, size.width + 30.0);
  std::uniform_real_distribution<double> y(-30.0, size.height + 30.0);
  std::uniform_real_distribution<double> fine_sigma(1.5, 3.5), coarse_sigma(6.0, 14.0);
  std::uniform_real_distribution<double> fine_amplitude(-90.0, 90.0), coarse_amplitude(-70.0, 70.0);
  const int fine_count = size.area() / 34, coarse_count = size.area() / 512;
  std::vector<Blob> blobs;
  for (int k = 0; k < fine_count; ++k) {
    blobs.push_back({x(rng), y(rng), fine_sigma(rng), fine_amplitude(rng)});
  }
  for (int k = 0; k < coarse_count; ++k) {
    blobs.push_back({x(rng), y(rng), coarse_sigma(rng), coarse_amplitude(rng)});
  }
  return blobs;
}

cv::Mat renderBlobs(const std::vector<Blob>& blobs, cv::Size size, double shift_x_px,
                    double shift_y_px) {
  cv::Mat accumulated(size, CV_64F, cv::Scalar(128.0));
  for (const Blob& b : blobs) {
    const double cx = b.x + shift_x_px;
    const double cy = b.y + shift_y_px;
    const int reach = static_cast<int>(std::ceil(4.0 * b.sigma));
    const int x0 = std::max(0, static_cast<int>(cx) - reach);
    const int x1 = std::min(size.width - 1, static_cast<int>(cx) + reach);
    const int y0 = std::max(0, static_cast<int>(cy) - reach);
    const int y1 = std::min(size.height - 1, static_cast<int>(cy) + reach);
    for (int y = y0; y <= y1; ++y) {
      double* row = accumulated.ptr<double>(y);
      for (int x = x0; x <= x1; ++x) {
        const double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
        row[x] += b.amplitude * std::exp(-r2 / (2.0 * b.sigma * b.sigma));
      }
    }
  }
  cv::Mat gray;
  accumulated.convertTo(gray, CV_8U);  // rounds and saturates
  return gray;
}

class FeatureTrackerTest : public ::testing::Test {
 protected:
  const cv::Size size_{640, 480};
  const std::vector<Blob> blobs_ = randomBlobs(size_, 7);
};

TEST_F(FeatureTrackerTest, CornersCoverEveryGridCellOfAUniformTexture) {
  const cv::Mat gray = renderBlobs(blobs_, size_, 0.0, 0.0);
  CornerDetectorOptions options;
  const std::vector<cv::Point2f> corners = detectUniformCorners(gray, options);

  std::vector<int> per_cell(options.grid_cols * options.grid_rows, 0);
  for (const cv::Point2f& p : corners) {
    ASSERT_GE(p.x, options.image_border_px);
    ASSERT_GE(p.y, options.image_border_px);
    ASSERT_LE(p.x, size_.width - 1 - options.image_border_px);
    ASSERT_LE(p.y, size_.height - 1 - options.image_border_px);
    const int c = static_cast<int>(p.x) * options.grid_cols / size_.width;
    const int r = static_cast<int>(p.y) * options.grid_rows / size_.height;
    ++per_cell[r * options.grid_cols + c];
  }
  for (int cell = 0; cell < static_cast<int>(per_cell.size()); ++cell) {
    EXPECT_GE(per_cell[cell], options.min_corners_per_cell) << "cell " << cell;
    EXPECT_LE(per_cell[cell], options.max_corners_per_cell) << "cell " << cell;
  }
}

TEST_F(FeatureTrackerTest, LowContrastCellStillGetsCornersByLoweringItsThreshold) {
  cv::Mat gray = renderBlobs(blobs_, size_, 0.0, 0.0);
  // Squash the contrast of the top-left cell to a tenth: the starting threshold finds nothing
  // there, the per-cell lowering must.
  CornerDetectorOptions options;
  const cv::Rect cell(0, 0, size_.width / options.grid_cols, size_.height / options.grid_rows);
  cv::Mat squashed = gray(cell);
  squashed.convertTo(squashed, CV_8U, 0.1, 115.0);

  CornerDetectorOptions fixed = options;
  fixed.fast_threshold_floor = fixed.fast_threshold_start;  // no lowering
  auto countIn = [&](const std::vector<cv::Point2f>& points) {
    return std::count_if(points.begin(), points.end(),
                         [&](const cv::Point2f& p) { return cell.contains(cv::Point(p)); });
  };
  EXPECT_EQ(countIn(detectUniformCorners(gray, fixed)), 0);
  EXPECT_GE(countIn(detectUniformCorners(gray, options)), options.min_corners_per_cell);
}

TEST_F(FeatureTrackerTest, TracksRecoverASubPixelShift) {
  const double shift_x = 1.37, shift_y = -0.64;  // pixels
  const cv::Mat a = renderBlobs(blobs_, size_, 0.0, 0.0);
  const cv::Mat b = renderBlobs(blobs_, size_, shift_x, shift_y);
  // OpenCV pads a KLT window that hangs over the image edge, which biases it by up to 0.2 px:
  // keep corners far enough in that their windows (radius 10 px) stay inside after the shift.
  CornerDetectorOptions detector;
  detector.image_border_px = 12;
  const FeatureTracker tracker(detector, KltOptions{});
  const std::vector<cv::Point2f> corners = detectUniformCorners(a, tracker.detectorOptions());
  const std::vector<FeatureMatch> matches = tracker.match(a, b);

  // Almost every corner survives a clean shift.
  ASSERT_GE(matches.size(), 0.95 * corners.size());
  double worst = 0.0;
  for (const FeatureMatch& m : matches) {
    const double ex = m.point_b_px.x - m.point_a_px.x - shift_x;
    const double ey = m.point_b_px.y - m.point_a_px.y - shift_y;
    worst = std::max(worst, std::hypot(ex, ey));
    EXPECT_LE(m.forward_backward_error_px, tracker.kltOptions().max_forward_backward_error_px);
  }
  EXPECT_LT(worst, 0.05) << "worst track error in px over " << matches.size() << " tracks";
}

TEST_F(FeatureTrackerTest, PointsPushedOutOfTheImageAreDropped) {
  const double shift_x = 30.0;  // pixels; corners in the right 30 px strip leave frame b
  const cv::Mat a = renderBlobs(blobs_, size_, 0.0, 0.0);
  const cv::Mat b = renderBlobs(blobs_, size_, shift_x, 0.0);
  const std::vector<cv::Point2f> corners = detectUniformCorners(a, CornerDetectorOptions{});
  // The margin also drops tracks whose window hangs over frame b's edge (biased, see above).
  KltOptions options;
  options.image_margin_px = 10.0;
  std::vector<TrackStatus> status;
  const std::vector<FeatureMatch> matches = trackFeatures(a, b, corners, options, &status);
  ASSERT_EQ(status.size(), corners.size());

  int leaving = 0;
  for (std::size_t k = 0; k < corners.size(); ++k) {
    if (corners[k].x + shift_x > size_.width - 1 - options.image_margin_px) {
      ++leaving;
      EXPECT_NE(status[k], TrackStatus::kTracked) << "corner " << corners[k];
    }
  }
  ASSERT_GT(leaving, 10);  // the test means something only if some corners do leave
  for (const FeatureMatch& m : matches) {
    EXPECT_LE(m.point_b_px.x, size_.width - 1 - options.image_margin_px);
    EXPECT_NEAR(m.point_b_px.x - m.point_a_px.x, shift_x, 0.05) << "from " << m.point_a_px;
    EXPECT_NEAR(m.point_b_px.y - m.point_a_px.y, 0.0, 0.05) << "from " << m.point_a_px;
  }
  EXPECT_EQ(matches.size(), static_cast<std::size_t>(
                                std::count(status.begin(), status.end(), TrackStatus::kTracked)));
}

TEST_F(FeatureTrackerTest, ForwardBackwardCheckDropsTracksIntoUnrelatedContent) {
  const double shift_x = 2.0, shift_y = 1.0;  // pixels
  const cv::Mat a = renderBlobs(blobs_, size_, 0.0, 0.0);
  cv::Mat b = renderBlobs(blobs_, size_, shift_x, shift_y);
  // An "occluder": a square of frame b replaced by an unrelated texture.
  const cv::Rect occluder(200, 150, 200, 160);
  const cv::Mat other = renderBlobs(randomBlobs(size_, 99), size_, 0.0, 0.0);
  other(occluder).copyTo(b(occluder));

  const std::vector<cv::Point2f> corners = detectUniformCorners(a, CornerDetectorOptions{});
  KltOptions no_check;
  no_check.max_forward_backward_error_px = 0.0;  // disabled
  const KltOptions checked;

  // Points well inside the occluder (further than a KLT window) have no true counterpart.
  const cv::Rect deep_inside(occluder.x + 15, occluder.y + 15, occluder.width - 30,
                             occluder.height - 30);
  auto wrongInside = [&](const std::vector<FeatureMatch>& matches) {
    int wrong = 0;
    for (const FeatureMatch& m : matches) {
      const double err = std::hypot(m.point_b_px.x - m.point_a_px.x - shift_x,
                                    m.point_b_px.y - m.point_a_px.y - shift_y);
      if (deep_inside.contains(cv::Point(m.point_a_px)) && err > 0.5) ++wrong;
    }
    return wrong;
  };
  const int wrong_unchecked = wrongInside(trackFeatures(a, b, corners, no_check));
  std::vector<TrackStatus> status;
  const std::vector<FeatureMatch> matches = trackFeatures(a, b, corners, checked, &status);
  // Without the check KLT happily reports wrong matches in the occluder; with it none survive.
  EXPECT_GT(wrong_unchecked, 5);
  EXPECT_EQ(wrongInside(matches), 0);
  EXPECT_GT(std::count(status.begin(), status.end(), TrackStatus::kForwardBackwardFailed), 5);
  // Outside the occluder tracking still works.
  int good_outside = 0;
  for (const FeatureMatch& m : matches) {
    if (!(occluder.contains(cv::Point(m.point_a_px)))) ++good_outside;
  }
  EXPECT_GT(good_outside, static_cast<int>(corners.size()) / 2);
}

TEST(FeatureTrackerInput, RejectsBadImagesAndOptions) {
  const cv::Mat color(100, 100, CV_8UC3, cv::Scalar::all(0));
  const cv::Mat gray(100, 100, CV_8UC1, cv::Scalar(0));
  EXPECT_THROW(detectUniformCorners(color, CornerDetectorOptions{}), std::invalid_argument);
  EXPECT_THROW(detectUniformCorners(cv::Mat(), CornerDetectorOptions{}), std::invalid_argument);
  EXPECT_THROW(trackFeatures(gray, cv::Mat(50, 50, CV_8UC1), {}, KltOptions{}),
               std::invalid_argument);
  CornerDetectorOptions bad_grid;
  bad_grid.grid_cols = 0;
  EXPECT_THROW(FeatureTracker(bad_grid, KltOptions{}), std::invalid_argument);
  KltOptions bad_window;
  bad_window.window_size_px = 20;
  EXPECT_THROW(FeatureTracker(CornerDetectorOptions{}, bad_window), std::invalid_argument);
  // A flat image has no corners and nothing to track; that is not an error.
  EXPECT_TRUE(FeatureTracker().match(gray, gray).empty());
}

}  // namespace
}  // namespace deep_ois
