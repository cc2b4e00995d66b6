// The per-pair check of a compensation against the images: the compensated per-patch homographies
// and the plain gyro's, both applied to the pair's point tracks, give a residual each (pixels) and a
// confidence; a pair whose model does worse than the plain gyro makes the pipeline fall back to the
// plain gyro, with hysteresis (CompensationFallback).
//
// Robust on purpose: tracks that neither motion explains (a moving object, a mismatch in low
// texture or in the dark) are rejected, not averaged in, and a pair with too few tracks left says
// nothing (not usable) rather than a noisy verdict. Pure OpenCV/Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

struct CompensationCheckOptions {
  // A track whose error exceeds this under both motions is an outlier (a moving object, a
  // mismatch): pixels of the camera image.
  double outlier_px = 2.0;
  // Fewer inliers than this: the pair is not usable for a verdict.
  int min_inliers = 12;
  // Inliers at which the confidence's track term reaches 1.
  int confident_inliers = 60;

  std::string validate() const;
};

struct CompensationCheck {
  bool usable = false;
  int tracks = 0;
  int inliers = 0;
  // Mean track error over the inliers (the same tracks for both), pixels: with the compensation
  // in use and with the plain gyro. NaN when not usable.
  double model_residual_px = 0.0;
  double gyro_residual_px = 0.0;
  // In [0, 1]: the share of tracks that are inliers times min(1, inliers / confident_inliers). 0
  // when not usable.
  double confidence = 0.0;
};

// `matches` on raw pixels of `camera` (frame a -> frame b); the homographies per row patch map
// undistorted pixels of frame a to frame b (patch of a track: its frame-a row). Throws
// std::invalid_argument when the two homography lists differ in size or are empty.
CompensationCheck checkCompensation(const CameraModel& camera, const std::vector<FeatureMatch>& matches,
                                    const std::vector<Eigen::Matrix3d>& model_homographies,
                                    const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                    const CompensationCheckOptions& options = {});

// The check of several compensations of one pair at once, on one common set of tracks (a track is
// an outlier when every motion, the plain gyro's included, misses it by more than outlier_px), so
// that their residuals compare pair by pair: how a swap on trial is judged against the model it
// replaced (confirmed_state.h).
struct CompensationComparison {
  bool usable = false;
  int tracks = 0;
  int inliers = 0;
  std::vector<double> residuals_px;  // per compensation given, mean over the inliers (NaN: unusable)
  double gyro_residual_px = 0.0;
};

// Throws std::invalid_argument when a homography list is empty or differs in size from the gyro's.
CompensationComparison compareCompensations(const CameraModel& camera, const std::vector<FeatureMatch>& matches,
                                            const std::vector<std::vector<Eigen::Matrix3d>>& compensations,
                                            const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                            const CompensationCheckOptions& options = {});

struct CompensationFallbackOptions {
  // The model is worse than the plain gyro on a pair when its residual exceeds the gyro's by this
  // fraction and by margin_px.
  double worse_fraction = 0.05;
  double margin_px = 0.02;
  int enter_after_pairs = 5;   // consecutive worse pairs before falling back
  int leave_after_pairs = 15;  // consecutive not-worse pairs before using the model again
};

// Hysteresis over the usable checks: unusable pairs change nothing.
class CompensationFallback {
 public:
  explicit CompensationFallback(CompensationFallbackOptions options = {}) : options_(options) {}
  // Returns whether the plain gyro should be used from now on.
  bool update(const CompensationCheck& check);
  bool fallingBack() const { return falling_back_; }
  void reset() { falling_back_ = false; streak_ = 0; }

 private:
  CompensationFallbackOptions options_;
  bool falling_back_ = false;
  int streak_ = 0;  // consecutive usable pairs pointing the other way
};

}  // namespace deep_ois
