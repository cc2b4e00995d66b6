// Fundamental Mixtures (paper section 3.2): per-row-patch camera rotations between two
// rolling-shutter frames, estimated from point tracks. These rotations are the network's training
// target. Pure Eigen: no ROS, no OpenCV calls beyond the FeatureMatch type.
//
// Accuracy note (synthetic, f = 300 px, 360x270, 50 tracks per patch): exact tracks give the
// rotations to 1e-5 degree; 0.3 px track noise gives 0.1 - 0.6 degree per patch, because F fixes
// only the flow across epipolar lines and one rotation direction of a 45-row strip is weak
// (the rotation / translation ambiguity). The rotation-only fit reaches 0.08 degree, which is
// why it is preferred unless the tracks show parallax (ModelSelection).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

// How the overall scale of the stacked unknowns f = (f_1 .. f_N) is fixed.
enum class MixtureScaleGauge {
  // <F_i, F_global> = 1 for every patch (normalised coordinates), F_global the robust global
  // fundamental matrix. With the paper's sigma = 0.001 h the weights are hard, A is block
  // diagonal and ||f|| = 1 leaves each F_i's scale free (the SVD returns one patch's F and zeros
  // elsewhere); this gauge gives every F_i a common scale, so the mixture sum is meaningful.
  kPerPatchGlobalReference,
  // The paper's literal ||f|| = 1 solved by SVD of A. Well posed only when the Gaussian weights
  // (or the smoothness rows) couple every patch to its neighbours, i.e. a sigma of several
  // percent of the height.
  kUnitNorm,
};

// How the rotations are chosen between the two fits made from the same tracks: the paper's F
// rotations (one F per patch, decomposed) and a rotation-only fit (one rotation per patch, fitted
// to the full 2-D flow).
enum class ModelSelection {
  // The rotation-only fit, unless the tracks show parallax (max_parallax_share). Why: F fixes only
  // the flow across epipolar lines; with the few millimetres a hand-held camera moves between two
  // frames, its rotations are poorly determined where rotation and translation look alike, and
  // the rolling-shutter change of rotation within a patch passes for translation. On the
  // simulator's hand-held RE pairs the F rotations were 2.6x further from the truth than the
  // rotation-only fit's (median 0.142 vs 0.054 degree; README, Fundamental Mixtures), and a
  // goodness-of-fit choice (Torr's GRIC, which asks whether parallax is visible at all, not
  // whether F's rotation is the better one) chose F for 57 % of them. With clear parallax the
  // rotation-only fit is biased towards the depth band it keeps, and F's rotation is the right one.
  kRotationUnlessParallax,
  // The paper's literal pipeline: the F rotations whenever F can be fitted and decomposed; the
  // rotation-only fit only when it cannot.
  kFundamental,
};

struct FundamentalMixturesOptions {
  int patch_count = 6;  // N row patches; patch i holds rows [i*h/N, (i+1)*h/N)
  // Gaussian weight sigma as a fraction of the image height. The paper's 0.001 h is 0.27 px at
  // h = 270: every point's weight is ~1 on its own patch and ~0 elsewhere (a hard assignment),
  // so neighbouring patches are tied only by the smoothness rows below.
  double weight_sigma_fraction = 0.001;
  // Patches whose summed weight is below this many points get lambda * (F_i - F_(i-1)) = 0
  // (and the same tie for the rotation-only fit). 8 = the linear F solver's minimum.
  double min_points_per_patch = 8.0;
  double smoothness_lambda = 1.0;  // weight of one tie row relative to one (unit) data row
  // Weight of a tie between every pair of neighbouring patch rotations in the refinement, as
  // lambda * f * log(R_i^T R_(i+1)) px. F fixes only the flow across epipolar lines, so in a
  // 45-row strip one rotation direction is weak and noise (or an outlier lying near its
  // epipolar line) swings it. A tie holds that direction but biases it towards the neighbours:
  // on the synthetic tests 0.5 cut the 0.3 px noise error from 0.26 to 0.16 degree mean, and
  // added 0.15 degree of bias on exact tracks. Off by default (the paper has no such tie).
  double rotation_tie_lambda = 0.0;
  MixtureScaleGauge scale_gauge = MixtureScaleGauge::kPerPatchGlobalReference;

  // Fewer matches (or inliers after the robust stage) than this: rejected.
  int min_inliers = 16;
  // Inliers must populate at least this many patches: with all points in one patch the other
  // patches would be pure extrapolation, which is not a training label.
  int min_populated_patches = 2;

  // Robust stage. Why this design: outliers (bad KLT tracks, moving objects) are found by MSAC
  // with the ransac_threshold_px, loose enough to accept the few tenths of a pixel (or more)
  // by which one global model misses rolling-shutter rows. Two candidate models are kept apart:
  // a fundamental matrix (8-point, handles parallax; one global MSAC, since an 8-point F from a
  // 45-row strip is too poorly conditioned to judge inliers) and a rotation (2-point Kabsch on
  // bearings; the right model for hand-held, nearly pure rotation where F is degenerate; global
  // MSAC, then a local MSAC per patch with at least 4 tracks). Each model is then refitted per
  // patch on its inliers and the inliers re-chosen from all matches with the tighter
  // inlier_threshold_px, up to refinement_iterations times.
  //
  // F path: the paper's linear mixture (A f = 0, a plain pass then one with rows divided by
  // their Sampson gradient), each F_i decomposed by cheirality; these rotations start a
  // Levenberg-Marquardt refinement of per-patch rotations R_i with one shared translation
  // direction on the Sampson distances (px). Sharing t leaves a patch only its 3 rotation dof
  // instead of 7 poorly conditioned ones; on exact tracks it reproduces the linear answer.

  // Sampson distance (F) or transfer error (rotation), px. Outliers within it of their epipolar
  // line enter the first linear solve and can start the refinement in a wrong basin: on exact
  // synthetic tracks with 20 % outliers, 3 px gave 0.27 degree mean worst-patch error, 2 px 0.07,
  // 1 px 0.02 (0.3 px noise: 0.52 for all three). Too tight loses the outer patches to the
  // rolling-shutter mismatch of the global model.
  double ransac_threshold_px = 2.0;
  double inlier_threshold_px = 1.0;  // same measures, for the refined per-patch models, px
  int ransac_max_iterations = 2000;
  double ransac_confidence = 0.999;  // adaptive stop: P(at least one all-inlier sample)
  int refinement_iterations = 4;
  std::uint32_t seed = 1;  // the RANSAC draws, through portable_random.h

  // Model selection: which of the two fits gives the rotations (see ModelSelection).
  ModelSelection model_selection = ModelSelection::kRotationUnlessParallax;
  // kRotationUnlessParallax: the F rotations are used when more than this fraction of the F
  // inliers are not inliers of the rotation-only fit (their parallax exceeds inlier_threshold_px).
  // Under pure rotation the share is not 0: F judges a track by its distance to a line, the
  // rotation by a 2-D distance, so noise and outliers near their epipolar lines count (synthetic,
  // 0.3 px noise and 20 % outliers: 0.08). Clear parallax (synthetic, 5 cm at 2-10 m): 0.33-0.6.
  double max_parallax_share = 0.2;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Which motion model produced the rotations.
enum class MotionModel {
  kNone,                        // rejected
  kFundamentalMixtures,         // one F per patch, decomposed (the paper)
  kGlobalFundamental,           // one F for the whole frame (the paper's ablation)
  kRotationOnlyFallback,        // per-patch rotations fitted directly (too little parallax)
  kGlobalRotationOnlyFallback,  // one rotation for the frame (global variant, pure rotation)
};

enum class FundamentalMixturesStatus {
  kOk,
  kTooFewMatches,     // fewer matches than min_inliers
  kTooFewInliers,     // the robust stage kept fewer than min_inliers
  kPointsInOnePatch,  // inliers populate fewer than min_populated_patches
  kDegenerate,        // neither model fits (e.g. F degenerate and no rotation consensus)
  kSolverFailure,     // a linear solve was singular or produced non-finite numbers
};

const char* toString(MotionModel model);
const char* toString(FundamentalMixturesStatus status);

struct FundamentalMixturesResult {
  FundamentalMixturesStatus status = FundamentalMixturesStatus::kOk;
  std::string reason;  // a sentence; empty when ok
  MotionModel model = MotionModel::kNone;
  // Per patch (patch_count entries when ok, identical for the global variant). F_i satisfies
  // x_b^T F_i x_a = 0 for undistorted pixels of frame a in patch i; it is the refined
  // K^-T [t]x R_i K^-1 (zero matrices when the rotation-only fallback was used). R_b_a maps camera
  // frame a to camera frame b; H_i = K R_i K^-1 with H[2][2] = 1 maps undistorted pixels of frame a
  // in patch i to frame b.
  std::vector<Eigen::Matrix3d> fundamentals;
  std::vector<Eigen::Matrix3d> rotations;
  std::vector<Eigen::Matrix3d> homographies;
  std::vector<int> inlier_counts;  // per patch, by the patch of the point's row in frame a
  int inlier_count = 0;
  std::vector<bool> inliers;  // one flag per input match
  // Median over inliers of |H_i x_a - x_b|, px: includes translation parallax by design.
  double median_rotation_residual_px = 0.0;
  // The fraction of the F inliers that the rotation-only fit rejects (see max_parallax_share);
  // 0 when only one of the two fits succeeded.
  double parallax_share = 0.0;
  bool ok() const { return status == FundamentalMixturesStatus::kOk; }
};

// The Fundamental Mixtures estimate between frame a (earlier) and frame b. Match pixels are raw;
// they are undistorted with `camera` when it has distortion, and patches are chosen by the raw
// row in frame a. Throws std::invalid_argument on invalid options or camera.
FundamentalMixturesResult estimateFundamentalMixtures(const std::vector<FeatureMatch>& matches,
                                                      const CameraModel& camera,
                                                      const FundamentalMixturesOptions& options);

// The ablation: one fundamental matrix (or rotation, when degenerate) for the whole frame, the
// same pipeline otherwise; returns patch_count identical rotations and homographies.
FundamentalMixturesResult estimateGlobalFundamental(const std::vector<FeatureMatch>& matches,
                                                    const CameraModel& camera,
                                                    const FundamentalMixturesOptions& options);

}  // namespace deep_ois
