// The rows of the paper's table that deep_ois computes itself, in the paper's order: identity;
// image baselines (one global homography from SIFT / ORB / AKAZE matches with RANSAC or MAGSAC++);
// the gyro (non-OIS camera, OIS camera uncompensated, or unspecified); the image-based ground
// truths (global F, Fundamental Mixtures). The shipped network is added after these by the
// evaluate tool (it lives in the net layer).
#pragma once

#include <string>
#include <vector>

#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/vision/feature_homography.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"

namespace deep_ois {

// Row names.
extern const char* const kIdentityMethod;    // "identity"
extern const char* const kGyroNonOisMethod;  // "gyro, non-OIS camera"
extern const char* const kGyroOisMethod;     // "gyro, OIS camera (uncompensated)"
extern const char* const kGyroMethod;        // "gyro" (recordings whose OIS state is not given)
extern const char* const kGyroLensLogMethod;  // "gyro + lens log" (OIS cameras that log their lens)
extern const char* const kGlobalFundamentalMethod;    // "global F ground truth"
extern const char* const kFundamentalMixturesMethod;  // "Fundamental Mixtures ground truth"

struct StandardMethodOptions {
  bool image_baselines = true;  // the six feature + robust estimator rows
  bool ground_truth = true;     // the global F and Fundamental Mixtures rows
  FeatureHomographyOptions features;
  // The offline training-set job's options (its defaults), so that the ground-truth rows are the
  // training target. solver.patch_count must be the gyro flow's patch count.
  CornerDetectorOptions corners;
  KltOptions klt;
  FundamentalMixturesOptions solver;
};

// No motion at all: the paper's I_3x3 row, and the cap of every other row.
AlignmentMethod identityMethod();
// The gyro homographies of the pair (the gyro flow nodelet's output) under the three names, each
// for its own pairs: non-OIS (annotated non-OIS recordings and the simulator's twins), OIS camera,
// and unspecified.
std::vector<AlignmentMethod> gyroMethods();
// The gyro flow nodelet's homographies with the camera's lens-shift log (OIS camera pairs); a pair
// the log does not cover is a failure (scored as identity and counted). Not among the standard
// rows: the evaluate tool adds it when a recording has a log.
AlignmentMethod gyroLensLogMethod();
// "<DETECTOR> + <ESTIMATOR>" for SIFT, ORB, AKAZE x RANSAC, MAGSAC; the two estimators of one
// detector share its features and matches (computed once per pair, each frame described once).
std::vector<AlignmentMethod> featureHomographyMethods(const FeatureHomographyOptions& options);
// Global F then Fundamental Mixtures, sharing the KLT tracks of a pair. A solver rejection is a
// failure (scored as identity). Throws std::invalid_argument on invalid options.
std::vector<AlignmentMethod> groundTruthMethods(const CornerDetectorOptions& corners,
                                                const KltOptions& klt,
                                                const FundamentalMixturesOptions& solver);
// All of the above in the paper's order.
std::vector<AlignmentMethod> standardAlignmentMethods(const StandardMethodOptions& options);

}  // namespace deep_ois
