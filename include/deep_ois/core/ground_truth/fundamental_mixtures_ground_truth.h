// The image-based ground truth of deep_ois from two grey frames: spatially uniform FAST corners in
// frame a tracked into frame b by KLT (feature_tracker.h), then the Fundamental Mixtures solver or
// its global-F ablation (fundamental_mixtures.h). The offline training-set job and the evaluator
// both call this, so the training target and the evaluated "ground truth" rows are one code path.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"

namespace deep_ois {

enum class GroundTruthModel {
  kFundamentalMixtures,  // one F per row patch (the paper's ground truth)
  kGlobalFundamental,    // one F for the whole frame (the paper's ablation)
};

class FundamentalMixturesGroundTruth {
 public:
  // Throws std::invalid_argument naming the bad field when an options struct is invalid.
  FundamentalMixturesGroundTruth(const CornerDetectorOptions& corners, const KltOptions& klt,
                                 const FundamentalMixturesOptions& solver);

  // KLT tracks of uniform corners of gray_a into gray_b (CV_8UC1 of one size).
  std::vector<FeatureMatch> track(const cv::Mat& gray_a, const cv::Mat& gray_b) const;
  // The rotation-only per-patch homographies of the model from the tracks (raw pixels; undistorted
  // with `camera` inside the solver).
  FundamentalMixturesResult solve(const std::vector<FeatureMatch>& matches,
                                  const CameraModel& camera, GroundTruthModel model) const;

  const FundamentalMixturesOptions& solverOptions() const { return solver_; }

 private:
  FeatureTracker tracker_;
  FundamentalMixturesOptions solver_;
};

}  // namespace deep_ois
