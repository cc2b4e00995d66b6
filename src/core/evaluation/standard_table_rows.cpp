#include "deep_ois/core/evaluation/standard_table_rows.h"

#include <memory>
#include <tuple>

#include "deep_ois/core/ground_truth/fundamental_mixtures_ground_truth.h"

namespace deep_ois {

const char* const kIdentityMethod = "identity";
const char* const kGyroNonOisMethod = "gyro, non-OIS camera";
const char* const kGyroOisMethod = "gyro, OIS camera (uncompensated)";
const char* const kGyroMethod = "gyro";
const char* const kGyroLensLogMethod = "gyro + lens log";
const char* const kGlobalFundamentalMethod = "global F ground truth";
const char* const kFundamentalMixturesMethod = "Fundamental Mixtures ground truth";

namespace {

// Which pair a cached result belongs to.
using PairKey = std::tuple<std::uint64_t, std::int64_t, std::int64_t>;
PairKey pairKey(const FramePairContext& pair) {
  return {pair.recording_id, pair.stamp_a_ns, pair.stamp_b_ns};
}

// The result of the current pair, computed once for the rows that share it (pairs come one at a
// time, in order).
template <typename Value>
class CurrentPairResult {
 public:
  template <typename Compute>
  const Value& get(const FramePairContext& pair, Compute compute) {
    if (!valid_ || key_ != pairKey(pair)) {
      valid_ = false;  // stays false if compute throws
      value_ = compute();
      key_ = pairKey(pair);
      valid_ = true;
    }
    return value_;
  }

 private:
  bool valid_ = false;
  PairKey key_;
  Value value_;
};

// One detector's matches of the current pair, shared by its RANSAC and MAGSAC rows.
struct SharedMatches {
  SharedMatches(FeatureDetector detector, const FeatureHomographyOptions& options)
      : matcher(detector, options) {}
  const PointMatches& of(const FramePairContext& pair) {
    return current.get(pair, [&] {
      return matcher.match({pair.recording_id, pair.stamp_a_ns}, pair.gray_a,
                           {pair.recording_id, pair.stamp_b_ns}, pair.gray_b);
    });
  }
  FeatureMatcher matcher;
  CurrentPairResult<PointMatches> current;
};

// The KLT tracks of the current pair, shared by the two ground-truth rows.
struct SharedTracks {
  explicit SharedTracks(const FundamentalMixturesGroundTruth& gt) : ground_truth(gt) {}
  const std::vector<FeatureMatch>& of(const FramePairContext& pair) {
    return current.get(pair, [&] { return ground_truth.track(pair.gray_a, pair.gray_b); });
  }
  FundamentalMixturesGroundTruth ground_truth;
  CurrentPairResult<std::vector<FeatureMatch>> current;
};

AlignmentMethod gyroMethod(const char* name, unsigned scope) {
  return {name, scope, [](const FramePairContext& pair) {
            return AlignmentEstimate::patchHomographies(pair.gyro_homographies);
          }};
}

}  // namespace

AlignmentMethod identityMethod() {
  return {kIdentityMethod, kBenchmarkPairs, [](const FramePairContext&) {
            return AlignmentEstimate::rawHomography(Eigen::Matrix3d::Identity());
          }};
}

std::vector<AlignmentMethod> gyroMethods() {
  return {gyroMethod(kGyroNonOisMethod, kNonOisCameraPairs | kNonOisTwinPairs),
          gyroMethod(kGyroOisMethod, kOisCameraPairs),
          gyroMethod(kGyroMethod, kUnspecifiedCameraPairs)};
}

AlignmentMethod gyroLensLogMethod() {
  return {kGyroLensLogMethod, kOisCameraPairs, [](const FramePairContext& pair) {
            if (pair.lens_log_homographies.empty()) {
              return AlignmentEstimate::failed("the recording's lens-shift log does not cover the pair");
            }
            return AlignmentEstimate::patchHomographies(pair.lens_log_homographies);
          }};
}

std::vector<AlignmentMethod> featureHomographyMethods(const FeatureHomographyOptions& options) {
  std::vector<AlignmentMethod> methods;
  for (const FeatureDetector detector :
       {FeatureDetector::kSift, FeatureDetector::kOrb, FeatureDetector::kAkaze}) {
    const auto shared = std::make_shared<SharedMatches>(detector, options);
    for (const RobustEstimator estimator : {RobustEstimator::kRansac, RobustEstimator::kMagsac}) {
      methods.push_back(
          {std::string(toString(detector)) + " + " + toString(estimator), kBenchmarkPairs,
           [shared, estimator, options](const FramePairContext& pair) {
             const HomographyFit fit = fitHomography(shared->of(pair), estimator, options);
             if (!fit.ok) return AlignmentEstimate::failed(fit.reason);
             Eigen::Matrix3d H;
             for (int r = 0; r < 3; ++r)
               for (int c = 0; c < 3; ++c) H(r, c) = fit.H(r, c);
             return AlignmentEstimate::rawHomography(H);
           }});
    }
  }
  return methods;
}

std::vector<AlignmentMethod> groundTruthMethods(const CornerDetectorOptions& corners,
                                                const KltOptions& klt,
                                                const FundamentalMixturesOptions& solver) {
  const auto shared =
      std::make_shared<SharedTracks>(FundamentalMixturesGroundTruth(corners, klt, solver));
  std::vector<AlignmentMethod> methods;
  for (const auto& [name, model] :
       {std::make_pair(kGlobalFundamentalMethod, GroundTruthModel::kGlobalFundamental),
        std::make_pair(kFundamentalMixturesMethod, GroundTruthModel::kFundamentalMixtures)}) {
    methods.push_back(
        {name, kBenchmarkPairs, [shared, model = model](const FramePairContext& pair) {
           const FundamentalMixturesResult result =
               shared->ground_truth.solve(shared->of(pair), *pair.camera, model);
           if (!result.ok()) return AlignmentEstimate::failed(toString(result.status));
           return AlignmentEstimate::patchHomographies(result.homographies);
         }});
  }
  return methods;
}

std::vector<AlignmentMethod> standardAlignmentMethods(const StandardMethodOptions& options) {
  std::vector<AlignmentMethod> methods = {identityMethod()};
  if (options.image_baselines) {
    for (AlignmentMethod& method : featureHomographyMethods(options.features))
      methods.push_back(std::move(method));
  }
  for (AlignmentMethod& method : gyroMethods()) methods.push_back(std::move(method));
  if (options.ground_truth) {
    for (AlignmentMethod& method :
         groundTruthMethods(options.corners, options.klt, options.solver)) {
      methods.push_back(std::move(method));
    }
  }
  return methods;
}

}  // namespace deep_ois
