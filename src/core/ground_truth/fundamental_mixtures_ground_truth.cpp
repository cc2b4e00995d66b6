#include "deep_ois/core/ground_truth/fundamental_mixtures_ground_truth.h"

#include <stdexcept>

namespace deep_ois {

FundamentalMixturesGroundTruth::FundamentalMixturesGroundTruth(
    const CornerDetectorOptions& corners, const KltOptions& klt,
    const FundamentalMixturesOptions& solver)
    : tracker_(corners, klt), solver_(solver) {
  const std::string problem = solver.validate();
  if (!problem.empty()) throw std::invalid_argument("Fundamental Mixtures solver: " + problem);
}

std::vector<FeatureMatch> FundamentalMixturesGroundTruth::track(const cv::Mat& gray_a,
                                                                const cv::Mat& gray_b) const {
  return tracker_.match(gray_a, gray_b);
}

FundamentalMixturesResult FundamentalMixturesGroundTruth::solve(
    const std::vector<FeatureMatch>& matches, const CameraModel& camera,
    GroundTruthModel model) const {
  return model == GroundTruthModel::kGlobalFundamental
             ? estimateGlobalFundamental(matches, camera, solver_)
             : estimateFundamentalMixtures(matches, camera, solver_);
}

}  // namespace deep_ois
