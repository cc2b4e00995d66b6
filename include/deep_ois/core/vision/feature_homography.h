// The image baselines of the paper's table: one global homography between two frames from
// feature matches (SIFT, ORB or AKAZE descriptors, Lowe's ratio test) and a robust fit (RANSAC or
// MAGSAC++ through OpenCV's USAC). Pure OpenCV: no ROS.
//
// Parameters are OpenCV's defaults for each detector (SIFT: all features, contrast threshold
// 0.04; ORB: 500 features, 8 levels; AKAZE: threshold 0.001), brute-force matching with the
// descriptor's norm (L2 for SIFT, Hamming for ORB and AKAZE), ratio test 0.75, and
// findHomography with a 3 px reprojection threshold, 2000 iterations, confidence 0.995 for both
// robust estimators (MAGSAC++ reads the threshold as its largest noise sigma). SURF, the
// paper's other descriptor, is patented and not in Debian's OpenCV; AKAZE is the strong
// alternative it does have.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace deep_ois {

enum class FeatureDetector { kSift, kOrb, kAkaze };
enum class RobustEstimator { kRansac, kMagsac };

const char* toString(FeatureDetector detector);   // "SIFT", "ORB", "AKAZE"
const char* toString(RobustEstimator estimator);  // "RANSAC", "MAGSAC"

struct FeatureHomographyOptions {
  double ratio_test = 0.75;  // keep a match when best distance < ratio * second best (Lowe)
  // Fewer ratio-test matches than this: no estimate (the evaluator scores it as identity). 8
  // leaves a 4-point robust fit a few points to reject an outlier with.
  int min_matches = 8;
  double reprojection_threshold_px = 3.0;
  int max_iterations = 2000;
  double confidence = 0.995;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Matched keypoint positions, frame a -> frame b, pixels (OpenCV convention).
struct PointMatches {
  std::vector<cv::Point2f> points_a_px;
  std::vector<cv::Point2f> points_b_px;
  std::size_t keypoints_a = 0;
  std::size_t keypoints_b = 0;
};

// Names a frame for caches: its recording (unique in a run) and its stamp.
struct FrameId {
  std::uint64_t recording = 0;
  std::int64_t stamp_ns = 0;
  bool operator==(const FrameId& other) const {
    return recording == other.recording && stamp_ns == other.stamp_ns;
  }
};

// Detects, describes and matches one detector's features between two frames. Frames are named
// by an id (e.g. a stamp) so that a frame's features are computed once when it is frame b of one
// pair and frame a of the next: the last two frames are kept. Not thread-safe.
class FeatureMatcher {
 public:
  // Throws std::invalid_argument when the options are invalid.
  FeatureMatcher(FeatureDetector detector, const FeatureHomographyOptions& options);

  // Ratio-test matches from gray_a to gray_b (CV_8UC1). Ids must identify the image content:
  // a different image under a known id would reuse stale features.
  PointMatches match(const FrameId& id_a, const cv::Mat& gray_a, const FrameId& id_b,
                     const cv::Mat& gray_b);

  FeatureDetector detector() const { return detector_; }

 private:
  struct Features {
    FrameId id;
    bool valid = false;
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
  };
  // Index of the cache slot holding frame `id`, computing its features (in a slot other than
  // `keep_slot`) when it is not cached.
  int cachedFeatures(const FrameId& id, const cv::Mat& gray, int keep_slot);

  FeatureDetector detector_;
  FeatureHomographyOptions options_;
  cv::Ptr<cv::Feature2D> feature2d_;
  int norm_;
  Features cache_[2];
};

struct HomographyFit {
  bool ok = false;
  std::string reason;  // why there is no estimate; empty when ok
  cv::Matx33d H;       // frame a pixels -> frame b pixels, H(2,2) = 1
  int matches = 0;
  int inliers = 0;
};

// One global homography from matches with the robust estimator. Fails (ok = false) with fewer
// than options.min_matches matches, when OpenCV finds no model, or when it is not finite.
HomographyFit fitHomography(const PointMatches& matches, RobustEstimator estimator,
                            const FeatureHomographyOptions& options);

}  // namespace deep_ois
