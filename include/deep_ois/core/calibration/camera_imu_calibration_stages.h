// The stages of calibrateCameraImu() (camera_imu_calibration.h), each a function of plain data so
// that it can be run and tested alone:
//   1. coarse: a global search over time offsets and the 24 signed axis permutations, no guess;
//   2. prerequisites: is there enough rotation for anything (and for the mount) to be observable;
//   3. refinement: Levenberg-Marquardt over the estimated parameters, Cauchy loss by reweighting;
//   4. uncertainty: the statistical and the reported 1-sigma, and what they refuse.
// calibrateCameraImu() composes them and adds the checks that need a second run (a mount off its
// axis permutation, a readout at its bound). Pure Eigen.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/calibration_reprojection_problem.h"
#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/calibration/camera_imu_coarse_alignment.h"
#include "deep_ois/core/gyro/gyro_orientation_table.h"

namespace deep_ois {

// Which parameters (calibration_parameter layout) the options estimate.
using ActiveParameters = std::array<bool, calibration_parameter::kCount>;
ActiveParameters activeParameters(const CalibrationOptions& options);

// ---- 1. Coarse, global stage. ---------------------------------------------------------------
struct CoarseStage {
  std::vector<CoarsePair> pairs;  // one per prepared pair, in order: its fitted image rotation
  CoarseAlignment alignment;
  // Where the refinement starts: the coarse offset, rotation and bias for the estimated
  // quantities, the options' values for the held ones, the readout at `initial_readout_s`.
  CalibrationState start;
};

// Fits each pair's image rotation and searches the offset grid x 24 permutations (only the held
// offset / rotation when those are held). `zero_bias_gyro` integrates the gyro without a bias.
CoarseStage runCoarseStage(const std::vector<PreparedPair>& pairs, const GyroOrientationTable& zero_bias_gyro,
                           const CalibrationOptions& options, double initial_readout_s, double focal_px);

// ---- 2. Motion prerequisites. ---------------------------------------------------------------
struct MotionCheck {
  Eigen::Vector3d rate_rms_rad_s = Eigen::Vector3d::Zero();  // gyro RMS about its principal axes, descending
  std::string rates_text;                                    // the same, "a, b, c rad/s"
  double median_image_rotation_px = 0.0;
  // Non-empty: too little motion for any quantity (a refusal sentence with the remedy).
  std::string unobservable;
  // Non-empty: the mount is unobservable (rotation about one axis only), the rest may be.
  std::string rotation_unobservable;
};

// The gyro's principal RMS rates over the frames' span (at the start state's offset and bias) and
// the median image rotation the tracks see between frames, against the options' minima.
MotionCheck checkMotionPrerequisites(const CalibrationData& data, const std::vector<CoarsePair>& coarse_pairs,
                                     const CalibrationState& start, const CalibrationOptions& options,
                                     double max_readout_s, double focal_px);

// ---- 3. Refinement. ---------------------------------------------------------------------------
// Cauchy weights from the residuals: scale = factor x robust sigma (MAD of the residual norm),
// at least min_robust_scale_px; `scale_px` (optional) receives the scale.
std::vector<double> cauchyWeights(const std::vector<double>& residual_norms_px, const CalibrationOptions& options,
                                  double* scale_px);

struct Refinement {
  int iterations = 0;
  bool converged = false;                   // steps negligible (or none lowers the cost) before the cap
  double initial_median_residual_px = 0.0;  // at the start state (lens shifts fitted to it)
  std::vector<double> weights;              // the Cauchy weights of the last accepted step, per track
};

// Levenberg-Marquardt from `state` (moved to the estimate) over the active parameters, by the
// package's solver (minimiseLevenbergMarquardt, core/common/nonlinear_least_squares.h); held ones
// do not move. The lens shifts (when modelled) start at their best fit to the start state.
Refinement refineCalibration(ReprojectionProblem& problem, const ActiveParameters& active,
                             const CalibrationOptions& options, double max_readout_s, CalibrationState& state);

// ---- 4. Uncertainty. --------------------------------------------------------------------------
struct CalibrationUncertainty {
  double median_residual_px = 0.0;
  double inlier_fraction = 0.0;  // tracks with a Cauchy weight above 0.5
  // Per parameter (calibration_parameter layout): the statistical 1-sigma (the larger of
  // sigma^2 (J^T W J)^-1 and the block cluster-robust covariance; 0 for a held parameter), the
  // part a held value's own 1-sigma (CalibrationOptions::held_*_sigma) moves it by, and the
  // reported 1-sigma (the statistical one inflated, the systematic and the held parts added in
  // quadrature; a held parameter reports its held 1-sigma).
  CalibrationParameterVector statistical = CalibrationParameterVector::Zero();
  CalibrationParameterVector from_held = CalibrationParameterVector::Zero();
  CalibrationParameterVector reported = CalibrationParameterVector::Zero();
};

CalibrationUncertainty estimateUncertainty(ReprojectionProblem& problem, const CalibrationState& state,
                                           const std::vector<double>& weights, const ActiveParameters& active,
                                           const CalibrationOptions& options);

// The refusal of every estimated quantity whose statistical 1-sigma exceeds its limit (what is
// missing from the motion and what to do), marked in `refused`; `rates_text` names the gyro's
// principal rates.
std::vector<std::string> uncertaintyRefusals(const CalibrationResult::Sigmas& statistical,
                                             const CalibrationOptions& options, const std::string& rates_text,
                                             CalibrationResult::Refused& refused);

}  // namespace deep_ois
