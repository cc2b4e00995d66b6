// The fused motion of one frame pair: the compensated gyro motion (a prior, per row patch, with an
// uncertainty) refined by the pair's point tracks wherever they agree with it, and left alone where
// they do not.
//
// Why: the gyro cannot see parallax, its own noise or a residual calibration error, so even a
// perfect stabiliser model stops at the gyro's ceiling; the tracks the pipeline already follows
// can see them wherever there is texture. Where there is none (low texture, the dark) or where the
// tracks follow a moving object, the images are not evidence and the prior must stand alone.
//
// The model: per row patch i, a small correction of the prior homography P_i,
//   H_i = T(d_i) K exp([w_i]x) K^-1 P_i,
// a rotation w_i (rad, in frame b's camera frame) and a lens shift d_i (pixels of frame b): 5
// numbers a patch. The estimate minimises, over every correction at once,
//   sum_tracks rho(|b - H_i a|) / noise^2                  (Cauchy rho on the transfer error)
//   + sum_patches |pixels(c_i)|^2 / prior_sigma^2           (the prior: no correction)
//   + sum_neighbours |pixels(c_i - c_i+1)|^2 / smoothness^2 (neighbouring patches move together)
// where pixels(c) are the components' image displacements (focal * rotation about x, y; RMS
// radius * rotation about z; the shift), so a patch without tracks is held by its neighbours and
// the prior. The correction is linearised around the current estimate and solved by iteratively
// reweighted least squares with the package's robust ridge regression (RobustRidgeRegression,
// core/common/nonlinear_least_squares.h, without a ridge).
//
// Moving objects and mismatches are rejected twice: a track whose transfer error under the prior
// lies far beyond the prior's uncertainty (the given one, or the pair's own robust scale where that
// is smaller) never enters (the consistency test), and the Cauchy loss with a hard cut in the last
// passes drops the tracks the fit cannot explain. Too few
// consistent tracks, a small share of them, or a fit that does not explain the tracks better than
// the prior: the prior is returned unchanged (bit for bit), with the reason. Pure Eigen/OpenCV
// types: no ROS, no torch.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

// The motion the images refine: the compensated gyro's homographies per row patch (undistorted
// pixels of frame a in patch i -> frame b, the convention of rolling_shutter_homographies.h) and
// how far they may be off.
struct MotionPrior {
  std::vector<Eigen::Matrix3d> homographies;
  // The prior's 1-sigma transfer error at a pixel, per axis, pixels: e.g. the model residual of the
  // compensation's recent per-pair checks (compensation_check.h; benchmark_fusion takes the median
  // of the last 10), which also holds the tracks' noise and so errs on the large side; each pair
  // lowers it to what its own tracks show (FusionOptions::min_sigma_px).
  double sigma_px = 0.5;
};

struct FusionOptions {
  // 1-sigma of a track's position per axis (KLT noise), pixels.
  double track_noise_px = 0.2;
  // Scale of the Cauchy loss on a track's transfer error, pixels: weight 1 / (1 + (|r| / scale)^2).
  double cauchy_px = 0.3;
  // In the second half of the passes, tracks whose transfer error exceeds this are dropped: a
  // moving object's tracks that came within the consistency test. Tight on purpose, as the lens
  // ground truth's (lens_shift_ground_truth.h): a background track fits to the KLT noise. On the
  // synthetic tracks of test_fused_motion, an object moving 1.4 px against the background over 30 %
  // of the frame left 0.03 px of error at 0.6 px and 0.05-0.17 px at 1 px.
  double outlier_px = 0.6;
  // A track whose transfer error under the prior exceeds consistency_sigmas * sqrt(sigma^2 +
  // noise^2) (sigma = the prior's, noise = track_noise_px) disagrees with the prior: left out.
  double consistency_sigmas = 3.0;
  // The prior's sigma on a pair is the given one, or less where the lower quartile of the pair's
  // transfer errors under the prior shows it closer (a sigma from recent checks also holds their
  // moving objects); never below this, pixels.
  double min_sigma_px = 0.05;
  // 1-sigma of the change of the correction between neighbouring patches, in pixels of image
  // displacement per component.
  double smoothness_px = 0.1;
  // Fewer tracks than this consistent with the prior: the prior is kept.
  int min_tracks = 24;
  // A smaller share of the pair's tracks than this consistent with the prior: the images disagree
  // with the prior as a whole (a wrong prior, or the view is a moving object); the prior is kept.
  double min_consistent_share = 0.25;
  int iterations = 6;  // linearise-and-reweight passes

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// The correction of one row patch (what moved the prior there).
struct PatchCorrection {
  Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();  // in frame b's camera frame
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();       // lens shift, pixels of frame b
  int inliers = 0;                                          // tracks of this patch used at the end
};

struct FusedMotion {
  // Per row patch; the prior's, bit for bit, when not refined.
  std::vector<Eigen::Matrix3d> homographies;
  bool refined = false;
  std::vector<PatchCorrection> corrections;  // per patch (zero when not refined)
  int tracks = 0;             // given
  int consistent_tracks = 0;  // within the prior's consistency test
  int inliers = 0;            // used by the final pass
  // The prior's sigma used on this pair (options.min_sigma_px), pixels; the given one without tracks.
  double sigma_px = 0.0;
  // How far the fused motion moved from the prior, over a grid of the frame, pixels (0: not refined).
  double mean_correction_px = 0.0;
  double max_correction_px = 0.0;
  // Mean transfer error over the final inliers, pixels, under the prior and the fused motion (NaN
  // when no fit ran).
  double prior_residual_px = 0.0;
  double fused_residual_px = 0.0;
  // One sentence: "refined on 180 tracks, mean correction 0.31 px" or "prior kept: 3 tracks ...".
  std::string reason;
};

// `matches` on raw pixels of `camera` (frame a -> frame b); a track's patch is that of its frame-a
// row (patchIndexOfRow). Throws std::invalid_argument for invalid options, an empty or non-finite
// prior, or a non-positive or non-finite prior sigma.
FusedMotion fuseMotion(const CameraModel& camera, const MotionPrior& prior,
                       const std::vector<FeatureMatch>& matches, const FusionOptions& options = {});

// The homography of `prior` corrected by `correction` (the model above).
Eigen::Matrix3d correctedHomography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& prior,
                                    const PatchCorrection& correction);

}  // namespace deep_ois
