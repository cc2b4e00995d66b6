#include "deep_ois/core/vision/feature_homography.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <stdexcept>

namespace deep_ois {

const char* toString(FeatureDetector detector) {
  switch (detector) {
    case FeatureDetector::kSift:
      return "SIFT";
    case FeatureDetector::kOrb:
      return "ORB";
    case FeatureDetector::kAkaze:
      return "AKAZE";
  }
  return "?";
}

const char* toString(RobustEstimator estimator) {
  switch (estimator) {
    case RobustEstimator::kRansac:
      return "RANSAC";
    case RobustEstimator::kMagsac:
      return "MAGSAC";
  }
  return "?";
}

std::string FeatureHomographyOptions::validate() const {
  if (!(ratio_test > 0.0 && ratio_test <= 1.0)) return "ratio_test must be in (0, 1]";
  if (min_matches < 4) return "min_matches must be >= 4 (a homography needs 4 points)";
  if (!(reprojection_threshold_px > 0.0)) return "reprojection_threshold_px must be positive";
  if (max_iterations < 1) return "max_iterations must be >= 1";
  if (!(confidence > 0.0 && confidence < 1.0)) return "confidence must be in (0, 1)";
  return "";
}

FeatureMatcher::FeatureMatcher(FeatureDetector detector, const FeatureHomographyOptions& options)
    : detector_(detector), options_(options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("FeatureMatcher: " + problem);
  switch (detector) {
    case FeatureDetector::kSift:
      feature2d_ = cv::SIFT::create();
      norm_ = cv::NORM_L2;
      break;
    case FeatureDetector::kOrb:
      feature2d_ = cv::ORB::create();
      norm_ = cv::NORM_HAMMING;  // ORB's default WTA_K = 2
      break;
    case FeatureDetector::kAkaze:
      feature2d_ = cv::AKAZE::create();
      norm_ = cv::NORM_HAMMING;  // the default MLDB descriptor is binary
      break;
  }
}

int FeatureMatcher::cachedFeatures(const FrameId& id, const cv::Mat& gray, int keep_slot) {
  for (int slot = 0; slot < 2; ++slot) {
    if (cache_[slot].valid && cache_[slot].id == id) return slot;
  }
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw std::invalid_argument("FeatureMatcher: frames must be non-empty CV_8UC1");
  }
  // Replace the slot that is not kept (with none kept, an empty one first, else slot 0).
  const int slot = keep_slot >= 0 ? 1 - keep_slot : (cache_[0].valid && !cache_[1].valid ? 1 : 0);
  Features& features = cache_[slot];
  features.valid = false;
  features.keypoints.clear();
  features.descriptors.release();  // never write into a buffer a previous result may share
  feature2d_->detectAndCompute(gray, cv::noArray(), features.keypoints, features.descriptors);
  features.id = id;
  features.valid = true;
  return slot;
}

PointMatches FeatureMatcher::match(const FrameId& id_a, const cv::Mat& gray_a, const FrameId& id_b,
                                   const cv::Mat& gray_b) {
  const int slot_a = cachedFeatures(id_a, gray_a, -1);
  const Features& a = cache_[slot_a];
  const Features& b = cache_[cachedFeatures(id_b, gray_b, slot_a)];
  PointMatches matches;
  matches.keypoints_a = a.keypoints.size();
  matches.keypoints_b = b.keypoints.size();
  if (a.descriptors.empty() || b.descriptors.empty()) return matches;
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(norm_).knnMatch(a.descriptors, b.descriptors, knn, 2);
  for (const std::vector<cv::DMatch>& best : knn) {
    // A single candidate (frame b has one feature) cannot pass a ratio test.
    if (best.size() < 2 || !(best[0].distance < options_.ratio_test * best[1].distance)) continue;
    matches.points_a_px.push_back(a.keypoints[best[0].queryIdx].pt);
    matches.points_b_px.push_back(b.keypoints[best[0].trainIdx].pt);
  }
  return matches;
}

HomographyFit fitHomography(const PointMatches& matches, RobustEstimator estimator,
                            const FeatureHomographyOptions& options) {
  HomographyFit fit;
  fit.matches = static_cast<int>(matches.points_a_px.size());
  if (fit.matches < options.min_matches) {
    fit.reason = "too few matches (< " + std::to_string(options.min_matches) + ")";
    return fit;
  }
  const int method = estimator == RobustEstimator::kRansac ? cv::RANSAC : cv::USAC_MAGSAC;
  std::vector<unsigned char> inlier_mask;
  const cv::Mat H = cv::findHomography(matches.points_a_px, matches.points_b_px, method,
                                       options.reprojection_threshold_px, inlier_mask,
                                       options.max_iterations, options.confidence);
  if (H.empty()) {
    fit.reason = std::string(toString(estimator)) + " found no homography";
    return fit;
  }
  fit.H = cv::Matx33d(H);
  for (int k = 0; k < 9; ++k) {
    if (!std::isfinite(fit.H.val[k])) {
      fit.reason = "the homography is not finite";
      return fit;
    }
  }
  fit.inliers = cv::countNonZero(inlier_mask);
  fit.ok = true;
  return fit;
}

}  // namespace deep_ois
