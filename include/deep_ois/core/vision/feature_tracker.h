// Spatially uniform FAST corners and pyramidal KLT tracking with a forward-backward check.
// Pure OpenCV: no ROS. The point matches feed image-based motion estimates (e.g. Fundamental
// Mixtures), which need correspondences spread over the whole frame, not clustered on texture.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace deep_ois {

// Corner detection on a grid: each cell gets its own FAST threshold, so low-contrast regions
// still contribute corners while high-contrast ones do not take the whole budget.
struct CornerDetectorOptions {
  int grid_cols = 8;  // cells across the image width
  int grid_rows = 6;  // cells down the image height
  // Per cell, the threshold starts here and is lowered until the cell has min_corners_per_cell
  // corners or the floor is reached. Intensity levels of an 8-bit image.
  int fast_threshold_start = 40;
  int fast_threshold_floor = 5;
  // Each lowering multiplies the threshold by this factor (in (0, 1)); it drops by at least 1.
  double fast_threshold_factor = 0.5;
  int min_corners_per_cell = 8;    // stop lowering the threshold at this many corners
  int max_corners_per_cell = 12;   // keep at most this many, strongest FAST response first
  bool nonmax_suppression = true;  // FAST's own 3x3 non-maximum suppression
  // Corners closer than this to the image edge are dropped: a KLT window centred there would
  // hang outside the image, where OpenCV pads it and biases the track. Pixels; the default is
  // half the default KLT window.
  int image_border_px = 10;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Pyramidal Lucas-Kanade tracking, a -> b, then b -> a to check consistency.
struct KltOptions {
  int window_size_px = 21;   // square search window per pyramid level (odd)
  int pyramid_levels = 3;    // extra levels above full resolution (0 = no pyramid)
  int max_iterations = 30;   // per level
  double epsilon_px = 0.01;  // stop iterating when the update is below this
  // OpenCV's minimum eigenvalue of the window's spatial gradient matrix (normalised by the
  // window area): flat windows below it are reported lost.
  double min_eigen_threshold = 1e-4;
  // Keep a point only if tracking it a -> b -> a lands within this distance of where it
  // started. Pixels. A non-positive value or infinity disables the check.
  double max_forward_backward_error_px = 0.5;
  // Tracked points must end at least this far inside frame b's pixel centres, i.e. in
  // [margin, w - 1 - margin] x [margin, h - 1 - margin]. Pixels.
  double image_margin_px = 0.0;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// One tracked point: the same scene point in frame a and frame b, pixels (OpenCV convention).
struct FeatureMatch {
  cv::Point2f point_a_px;
  cv::Point2f point_b_px;
  float forward_backward_error_px = 0.0f;  // |a -> b -> a round trip - point_a_px|
};

// Why a point was kept or dropped by trackFeatures(); one entry per input point.
enum class TrackStatus {
  kTracked,
  kLost,                   // KLT did not converge (a -> b or b -> a), or the window was flat
  kOutsideImage,           // the point left frame b (or the margin)
  kForwardBackwardFailed,  // the a -> b -> a round trip missed by more than the threshold
};

const char* toString(TrackStatus status);

// Detects FAST corners spread over a grid. `gray` must be CV_8UC1. Points come cell by cell
// (row-major), strongest first within a cell. Throws std::invalid_argument on bad input or options.
std::vector<cv::Point2f> detectUniformCorners(const cv::Mat& gray,
                                              const CornerDetectorOptions& options);

// Tracks `points_a_px` from `gray_a` to `gray_b` (both CV_8UC1, same size) and returns the points
// that pass every check, in input order. When `status` is not null it receives one TrackStatus
// per input point. Throws std::invalid_argument on bad input or options.
std::vector<FeatureMatch> trackFeatures(const cv::Mat& gray_a, const cv::Mat& gray_b,
                                        const std::vector<cv::Point2f>& points_a_px,
                                        const KltOptions& options,
                                        std::vector<TrackStatus>* status = nullptr);

// An 8-bit single-channel view (or copy) of a frame of 1, 3 or 4 channels (RGB or BGR), 8 or 16 bit
// (16 bit scaled by 1/256). Throws std::invalid_argument for another depth.
cv::Mat toGray8(const cv::Mat& image);

// Detection in frame a followed by tracking into frame b, with fixed options. Stateless apart
// from its options, so one instance can serve several threads.
class FeatureTracker {
 public:
  FeatureTracker() = default;
  // Throws std::invalid_argument when either options struct is invalid.
  FeatureTracker(const CornerDetectorOptions& detector, const KltOptions& klt);

  std::vector<FeatureMatch> match(const cv::Mat& gray_a, const cv::Mat& gray_b) const;
  // match() on copies reduced to at most `max_width_px` wide (INTER_AREA; frames no wider are used
  // as they are), the tracks scaled back to the frames' pixels: the live pipeline's tracking, cheap
  // at any resolution. Frames as toGray8() takes them.
  std::vector<FeatureMatch> matchAtWidth(const cv::Mat& frame_a, const cv::Mat& frame_b, int max_width_px) const;

  const CornerDetectorOptions& detectorOptions() const { return detector_; }
  const KltOptions& kltOptions() const { return klt_; }

 private:
  CornerDetectorOptions detector_;
  KltOptions klt_;
};

}  // namespace deep_ois
