#include "deep_ois/core/vision/feature_tracker.h"

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

namespace {

// FAST compares a pixel with a Bresenham circle of this radius; cv::FAST skips that border.
constexpr int kFastRadiusPx = 3;

void checkGray(const cv::Mat& image, const char* name) {
  if (image.empty() || image.type() != CV_8UC1) {
    std::ostringstream why;
    why << name << " must be a non-empty CV_8UC1 image (got "
        << (image.empty() ? std::string("an empty image") : "type " + std::to_string(image.type()))
        << ")";
    throw std::invalid_argument(why.str());
  }
}

void throwIfInvalid(const std::string& why, const char* what) {
  if (!why.empty()) throw std::invalid_argument(std::string(what) + ": " + why);
}

// The next, lower FAST threshold; always strictly lower and never below the floor.
int lowerThreshold(int threshold, const CornerDetectorOptions& options) {
  const int scaled = static_cast<int>(std::floor(threshold * options.fast_threshold_factor));
  return std::max(options.fast_threshold_floor, std::min(threshold - 1, scaled));
}

// Corners of one cell, strongest first, at most max_corners_per_cell. `cell` is already clipped
// to the region where corners are allowed.
std::vector<cv::KeyPoint> detectInCell(const cv::Mat& gray, const cv::Rect& cell,
                                       const CornerDetectorOptions& options) {
  // FAST needs kFastRadiusPx of context around a candidate, so corners on the cell's own edge
  // are found by running on a slightly larger window and keeping only those inside the cell.
  const cv::Rect image_rect(0, 0, gray.cols, gray.rows);
  const cv::Rect window =
      cv::Rect(cell.x - kFastRadiusPx, cell.y - kFastRadiusPx, cell.width + 2 * kFastRadiusPx,
               cell.height + 2 * kFastRadiusPx) &
      image_rect;
  const cv::Mat roi = gray(window);
  std::vector<cv::KeyPoint> found;
  std::vector<cv::KeyPoint> in_cell;
  int threshold = options.fast_threshold_start;
  while (true) {
    cv::FAST(roi, found, threshold, options.nonmax_suppression);
    in_cell.clear();
    for (cv::KeyPoint& keypoint : found) {
      keypoint.pt.x += static_cast<float>(window.x);
      keypoint.pt.y += static_cast<float>(window.y);
      const cv::Point pixel(cvRound(keypoint.pt.x), cvRound(keypoint.pt.y));
      if (cell.contains(pixel)) in_cell.push_back(keypoint);
    }
    if (static_cast<int>(in_cell.size()) >= options.min_corners_per_cell ||
        threshold <= options.fast_threshold_floor) {
      break;
    }
    threshold = lowerThreshold(threshold, options);
  }
  // Stable, so equal responses keep FAST's raster order and results are reproducible.
  std::stable_sort(
      in_cell.begin(), in_cell.end(),
      [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  if (static_cast<int>(in_cell.size()) > options.max_corners_per_cell) {
    in_cell.resize(options.max_corners_per_cell);
  }
  return in_cell;
}

bool insideImage(const cv::Point2f& p, const cv::Size& size, double margin_px) {
  return std::isfinite(p.x) && std::isfinite(p.y) && p.x >= margin_px && p.y >= margin_px &&
         p.x <= size.width - 1 - margin_px && p.y <= size.height - 1 - margin_px;
}

}  // namespace

std::string CornerDetectorOptions::validate() const {
  std::ostringstream why;
  if (grid_cols < 1 || grid_rows < 1) {
    why << "grid_cols and grid_rows must be at least 1 (got " << grid_cols << "x" << grid_rows
        << ")";
  } else if (fast_threshold_floor < 1 || fast_threshold_start < fast_threshold_floor ||
             fast_threshold_start > 255) {
    why << "FAST thresholds must satisfy 1 <= fast_threshold_floor <= fast_threshold_start <= 255 "
        << "(got floor " << fast_threshold_floor << ", start " << fast_threshold_start << ")";
  } else if (!(fast_threshold_factor > 0.0 && fast_threshold_factor < 1.0)) {
    why << "fast_threshold_factor must be in (0, 1) (got " << fast_threshold_factor << ")";
  } else if (min_corners_per_cell < 0 || max_corners_per_cell < 1) {
    why << "min_corners_per_cell must be >= 0 and max_corners_per_cell >= 1 (got "
        << min_corners_per_cell << ", " << max_corners_per_cell << ")";
  } else if (image_border_px < 0) {
    why << "image_border_px must be >= 0 (got " << image_border_px << ")";
  }
  return why.str();
}

std::string KltOptions::validate() const {
  std::ostringstream why;
  if (window_size_px < 3 || window_size_px % 2 == 0) {
    why << "window_size_px must be odd and at least 3 (got " << window_size_px << ")";
  } else if (pyramid_levels < 0) {
    why << "pyramid_levels must be >= 0 (got " << pyramid_levels << ")";
  } else if (max_iterations < 1) {
    why << "max_iterations must be >= 1 (got " << max_iterations << ")";
  } else if (!(epsilon_px > 0.0) || !std::isfinite(epsilon_px)) {
    why << "epsilon_px must be a positive number of pixels (got " << epsilon_px << ")";
  } else if (!(min_eigen_threshold >= 0.0) || !std::isfinite(min_eigen_threshold)) {
    why << "min_eigen_threshold must be >= 0 (got " << min_eigen_threshold << ")";
  } else if (std::isnan(max_forward_backward_error_px)) {
    why << "max_forward_backward_error_px must not be NaN";
  } else if (!(image_margin_px >= 0.0) || !std::isfinite(image_margin_px)) {
    why << "image_margin_px must be >= 0 (got " << image_margin_px << ")";
  }
  return why.str();
}

const char* toString(TrackStatus status) {
  switch (status) {
    case TrackStatus::kTracked: return "tracked";
    case TrackStatus::kLost: return "lost";
    case TrackStatus::kOutsideImage: return "outside image";
    case TrackStatus::kForwardBackwardFailed: return "forward-backward check failed";
  }
  return "unknown";
}

std::vector<cv::Point2f> detectUniformCorners(const cv::Mat& gray,
                                              const CornerDetectorOptions& options) {
  checkGray(gray, "detectUniformCorners: image");
  throwIfInvalid(options.validate(), "detectUniformCorners");
  // Corners are allowed in the image shrunk by the border; cells split the full image, so their
  // layout does not depend on the border.
  const cv::Rect allowed(options.image_border_px, options.image_border_px,
                         gray.cols - 2 * options.image_border_px,
                         gray.rows - 2 * options.image_border_px);
  std::vector<cv::Point2f> corners;
  if (allowed.width <= 0 || allowed.height <= 0) return corners;
  for (int r = 0; r < options.grid_rows; ++r) {
    const int y0 = r * gray.rows / options.grid_rows;
    const int y1 = (r + 1) * gray.rows / options.grid_rows;
    for (int c = 0; c < options.grid_cols; ++c) {
      const int x0 = c * gray.cols / options.grid_cols;
      const int x1 = (c + 1) * gray.cols / options.grid_cols;
      const cv::Rect cell = cv::Rect(x0, y0, x1 - x0, y1 - y0) & allowed;
      if (cell.empty()) continue;
      for (const cv::KeyPoint& keypoint : detectInCell(gray, cell, options)) {
        corners.push_back(keypoint.pt);
      }
    }
  }
  return corners;
}

std::vector<FeatureMatch> trackFeatures(const cv::Mat& gray_a, const cv::Mat& gray_b,
                                        const std::vector<cv::Point2f>& points_a_px,
                                        const KltOptions& options,
                                        std::vector<TrackStatus>* status) {
  checkGray(gray_a, "trackFeatures: image a");
  checkGray(gray_b, "trackFeatures: image b");
  if (gray_a.size() != gray_b.size()) {
    throw std::invalid_argument("trackFeatures: images a and b differ in size");
  }
  throwIfInvalid(options.validate(), "trackFeatures");
  std::vector<TrackStatus> local_status;
  std::vector<TrackStatus>& outcome = status ? *status : local_status;
  outcome.assign(points_a_px.size(), TrackStatus::kLost);
  std::vector<FeatureMatch> matches;
  if (points_a_px.empty()) return matches;

  // Both directions run on the same pyramids, so build each once.
  const cv::Size window(options.window_size_px, options.window_size_px);
  std::vector<cv::Mat> pyramid_a, pyramid_b;
  const int levels_a =
      cv::buildOpticalFlowPyramid(gray_a, pyramid_a, window, options.pyramid_levels);
  const int levels_b =
      cv::buildOpticalFlowPyramid(gray_b, pyramid_b, window, options.pyramid_levels);
  const int levels = std::min(levels_a, levels_b);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                  options.max_iterations, options.epsilon_px);

  std::vector<cv::Point2f> forward;
  std::vector<unsigned char> forward_ok;
  std::vector<float> klt_error;
  cv::calcOpticalFlowPyrLK(pyramid_a, pyramid_b, points_a_px, forward, forward_ok, klt_error,
                           window, levels, criteria, 0, options.min_eigen_threshold);

  // Only points that survived the forward pass are tracked back.
  std::vector<int> candidates;
  std::vector<cv::Point2f> candidates_b;
  for (std::size_t k = 0; k < points_a_px.size(); ++k) {
    if (!forward_ok[k]) continue;
    if (!insideImage(forward[k], gray_b.size(), options.image_margin_px)) {
      outcome[k] = TrackStatus::kOutsideImage;
      continue;
    }
    candidates.push_back(static_cast<int>(k));
    candidates_b.push_back(forward[k]);
  }
  if (candidates.empty()) return matches;

  std::vector<cv::Point2f> backward;
  std::vector<unsigned char> backward_ok;
  cv::calcOpticalFlowPyrLK(pyramid_b, pyramid_a, candidates_b, backward, backward_ok, klt_error,
                           window, levels, criteria, 0, options.min_eigen_threshold);

  const bool check_fb = options.max_forward_backward_error_px > 0.0 &&
                        std::isfinite(options.max_forward_backward_error_px);
  for (std::size_t j = 0; j < candidates.size(); ++j) {
    const int k = candidates[j];
    if (!backward_ok[j]) continue;  // stays kLost
    const cv::Point2f miss = backward[j] - points_a_px[k];
    const float fb_error = std::hypot(miss.x, miss.y);
    if (!std::isfinite(fb_error) ||
        (check_fb && fb_error > options.max_forward_backward_error_px)) {
      outcome[k] = TrackStatus::kForwardBackwardFailed;
      continue;
    }
    outcome[k] = TrackStatus::kTracked;
    matches.push_back({points_a_px[k], forward[k], fb_error});
  }
  return matches;
}

FeatureTracker::FeatureTracker(const CornerDetectorOptions& detector, const KltOptions& klt)
    : detector_(detector), klt_(klt) {
  throwIfInvalid(detector_.validate(), "FeatureTracker: corner detector options");
  throwIfInvalid(klt_.validate(), "FeatureTracker: KLT options");
}

std::vector<FeatureMatch> FeatureTracker::match(const cv::Mat& gray_a,
                                                const cv::Mat& gray_b) const {
  return trackFeatures(gray_a, gray_b, detectUniformCorners(gray_a, detector_), klt_);
}

cv::Mat toGray8(const cv::Mat& image) {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);  // RGB or BGR: the weights differ slightly
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() == CV_16U) {
    cv::Mat scaled;
    gray.convertTo(scaled, CV_8U, 1.0 / 256.0);
    return scaled;
  }
  if (gray.depth() != CV_8U) throw std::invalid_argument("toGray8: frames must be 8 or 16 bit");
  return gray;
}

std::vector<FeatureMatch> FeatureTracker::matchAtWidth(const cv::Mat& frame_a, const cv::Mat& frame_b,
                                                       int max_width_px) const {
  cv::Mat a = toGray8(frame_a), b = toGray8(frame_b);
  double scale = 1.0;
  if (a.cols > max_width_px) {
    scale = static_cast<double>(a.cols) / max_width_px;
    const cv::Size reduced(max_width_px, static_cast<int>(std::lround(a.rows / scale)));
    cv::Mat ra, rb;
    cv::resize(a, ra, reduced, 0, 0, cv::INTER_AREA);
    cv::resize(b, rb, reduced, 0, 0, cv::INTER_AREA);
    a = ra;
    b = rb;
  }
  std::vector<FeatureMatch> matches = match(a, b);
  if (scale != 1.0) {
    // Pixel centres: reduced (u + 0.5) * scale - 0.5.
    const auto up = [scale](cv::Point2f p) {
      return cv::Point2f(static_cast<float>((p.x + 0.5) * scale - 0.5), static_cast<float>((p.y + 0.5) * scale - 0.5));
    };
    for (FeatureMatch& m : matches) {
      m.point_a_px = up(m.point_a_px);
      m.point_b_px = up(m.point_b_px);
    }
  }
  return matches;
}

}  // namespace deep_ois
