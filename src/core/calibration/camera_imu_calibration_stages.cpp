#include "deep_ois/core/calibration/camera_imu_calibration_stages.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

// The layout's names, short, as the formulas below use them.
constexpr int kParameterCount = calibration_parameter::kCount;
using calibration_parameter::kBias;
using calibration_parameter::kOffset;
using calibration_parameter::kReadout;
using calibration_parameter::kRotation;
using ParameterVector = CalibrationParameterVector;
using ParameterMatrix = CalibrationParameterMatrix;

// Pairs per cluster of the cluster-robust covariance: 5 pairs (1/6 s at 30 fps), about the time
// over which hand-held translation and the lens stay correlated.
constexpr std::size_t kPairsPerCluster = 5;

std::string describeSeconds(double seconds) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << seconds * 1e3 << " ms";
  return out.str();
}

// Principal RMS rates of the gyro over [begin, end] (IMU clock), descending, bias removed.
Eigen::Vector3d principalRateRms(const std::vector<ImuSample>& gyro, double begin_s, double end_s,
                                 const Eigen::Vector3d& bias) {
  Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
  int count = 0;
  for (const ImuSample& sample : gyro) {
    if (sample.stamp_s < begin_s || sample.stamp_s > end_s) continue;
    const Eigen::Vector3d w = sample.angular_velocity_rad_s - bias;
    moment += w * w.transpose();
    ++count;
  }
  if (count == 0) return Eigen::Vector3d::Zero();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(moment / count);
  const Eigen::Vector3d values = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // ascending
  return Eigen::Vector3d(values(2), values(1), values(0));
}

// Held parameters get a unit diagonal and no gradient: their step is exactly zero, and fixed-size
// 8x8 algebra serves every combination.
void restrictToActive(const CalibrationEvaluation& evaluation, const ActiveParameters& active, ParameterMatrix& H,
                      ParameterVector& g) {
  H = evaluation.H;
  g = evaluation.g;
  for (int i = 0; i < kParameterCount; ++i) {
    if (active[i]) continue;
    H.row(i).setZero();
    H.col(i).setZero();
    H(i, i) = 1.0;
    g(i) = 0.0;
  }
}

}  // namespace

ActiveParameters activeParameters(const CalibrationOptions& options) {
  ActiveParameters active{};
  active[kOffset] = options.estimate_time_offset;
  active[kReadout] = options.estimate_readout_time;
  for (int i = 0; i < 3; ++i) {
    active[kBias + i] = options.estimate_gyro_bias;
    active[kRotation + i] = options.estimate_rotation;
  }
  return active;
}

CoarseStage runCoarseStage(const std::vector<PreparedPair>& pairs, const GyroOrientationTable& zero_bias_gyro,
                           const CalibrationOptions& options, double initial_readout_s, double focal_px) {
  CoarseStage stage;
  // An OIS lens shift disturbs the pairs' rotation fits by pixels; a wider loss keeps them.
  const double coarse_scale_px = options.lens_shift == LensShiftHandling::kNone ? 1.0 : 3.0;
  for (const PreparedPair& pair : pairs) {
    CoarsePair coarse;
    coarse.stamp_a_s = pair.stamp_a_s;
    coarse.stamp_b_s = pair.stamp_b_s;
    double rows = 0.0;
    for (const TrackPoint& point : pair.points) rows += point.row_fraction_a;
    coarse.mean_row_fraction = rows / pair.points.size();
    coarse.image_rotation_rad = fitImageRotation(pair.bearings_a, pair.bearings_b, coarse_scale_px / focal_px);
    stage.pairs.push_back(coarse);
  }
  CoarseAlignmentOptions coarse_options;
  coarse_options.max_abs_time_offset_s = options.estimate_time_offset ? options.max_abs_time_offset_s : 0.0;
  coarse_options.time_step_s = options.coarse_time_step_s;
  coarse_options.held_time_offset_s = options.time_offset_s;
  coarse_options.readout_time_s = initial_readout_s;
  coarse_options.search_rotation = options.estimate_rotation;
  coarse_options.held_rotation = options.imu_to_camera_rotation;
  coarse_options.scale_rad = coarse_scale_px / focal_px;
  stage.alignment = coarseCameraImuAlignment(zero_bias_gyro, stage.pairs, coarse_options);

  const CoarseAlignment& coarse = stage.alignment;
  CalibrationState& state = stage.start;
  state.time_offset_s = options.estimate_time_offset ? coarse.time_offset_s : options.time_offset_s;
  state.readout_time_s = initial_readout_s;
  state.bias = options.estimate_gyro_bias ? coarse.gyro_bias_rad_s : options.gyro_bias_rad_s;
  state.R_cam_imu = options.estimate_rotation ? coarse.imu_to_camera_rotation : options.imu_to_camera_rotation;
  return stage;
}

MotionCheck checkMotionPrerequisites(const CalibrationData& data, const std::vector<CoarsePair>& coarse_pairs,
                                     const CalibrationState& start, const CalibrationOptions& options,
                                     double max_readout_s, double focal_px) {
  MotionCheck check;
  const double first_s = data.frame_stamps_s.front() + start.time_offset_s;
  const double last_s = data.frame_stamps_s.back() + start.time_offset_s + max_readout_s;
  check.rate_rms_rad_s = principalRateRms(data.gyro, first_s, last_s, start.bias);
  std::ostringstream rates;
  rates << std::fixed << std::setprecision(3) << check.rate_rms_rad_s(0) << ", " << check.rate_rms_rad_s(1) << ", "
        << check.rate_rms_rad_s(2) << " rad/s";
  check.rates_text = rates.str();
  if (check.rate_rms_rad_s(0) < options.min_excitation_rate_rad_s) {
    std::ostringstream why;
    why << "motion: the camera hardly rotates (gyro RMS about its principal axes " << check.rates_text
        << "; at least " << options.min_excitation_rate_rad_s
        << " rad/s is needed about one axis, two for the rotation): no quantity is observable; record "
           "again while turning the camera by hand about all three axes";
    check.unobservable = why.str();
    return check;
  }
  // The rate check passes a still camera on a vibrating mount; what the tracks see between frames
  // is what carries the information.
  std::vector<double> image_rotation_px;
  for (const CoarsePair& pair : coarse_pairs) image_rotation_px.push_back(pair.image_rotation_rad.norm() * focal_px);
  check.median_image_rotation_px = median(image_rotation_px);
  if (check.median_image_rotation_px < options.min_median_image_rotation_px) {
    std::ostringstream why;
    why << std::fixed << std::setprecision(2)
        << "motion: the camera hardly rotates between frames (median " << check.median_image_rotation_px
        << " px of image rotation per frame pair, " << std::setprecision(3)
        << check.median_image_rotation_px / focal_px * kRadToDeg << " deg; at least " << std::setprecision(2)
        << options.min_median_image_rotation_px << " px, " << std::setprecision(3)
        << options.min_median_image_rotation_px / focal_px * kRadToDeg
        << " deg at this focal length, is needed): track noise and translation parallax are as large as the "
           "rotation, so no quantity is observable; record again while turning the camera by hand about "
           "all three axes";
    check.unobservable = why.str();
    return check;
  }
  if (options.estimate_rotation && check.rate_rms_rad_s(1) < options.min_excitation_rate_rad_s) {
    std::ostringstream why;
    why << "IMU-camera rotation: the gyro shows rotation about one axis only (RMS about its principal axes "
        << check.rates_text << "; at least " << options.min_excitation_rate_rad_s
        << " rad/s is needed about two axes): the rotation about that axis is unobservable; turn the "
           "camera about a second axis too, or hold the rotation at a known value";
    check.rotation_unobservable = why.str();
  }
  return check;
}

// Cauchy weights from the residuals: scale = factor x robust sigma (MAD of the 2-D residual
// norm: median |e| = 1.1774 sigma for isotropic Gaussian noise in 2-D, 0.6745 sigma once the
// parallax direction is removed and one component is left).
std::vector<double> cauchyWeights(const std::vector<double>& residual_norms_px,
                                  const CalibrationOptions& options, double* scale_px) {
  const double sigma = median(residual_norms_px) / (removesParallax(options) ? 0.6745 : 1.1774);
  const double scale = std::max(options.robust_scale_factor * sigma, options.min_robust_scale_px);
  if (scale_px) *scale_px = scale;
  std::vector<double> weights(residual_norms_px.size());
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const double r = residual_norms_px[i] / scale;
    weights[i] = 1.0 / (1.0 + r * r);
  }
  return weights;
}

namespace {

// The refinement as the solver's linearised problem (core/common/nonlinear_least_squares.h): the
// reprojection problem's normal equations over the calibration parameters, the lens shifts
// eliminated (Schur complement) and moved with every step by back-substitution; the Cauchy
// weights re-scaled from the residuals after every accepted step; converged once two steps in a
// row no longer matter (1 us, 1e-5 rad/s, 1e-6 rad).
class CalibrationRefinementProblem : public LinearisedLeastSquaresProblem {
 public:
  CalibrationRefinementProblem(ReprojectionProblem& problem, const ActiveParameters& active,
                               const CalibrationOptions& options, double max_readout_s,
                               CalibrationState& state, std::vector<double>& weights)
      : problem_(problem), active_(active), options_(options), max_readout_s_(max_readout_s),
        state_(state), weights_(weights) {}

  bool linearise(double* cost, Eigen::MatrixXd* normal, Eigen::VectorXd* gradient) override {
    current_ = problem_.evaluate(state_, weights_, true);
    ParameterMatrix H;
    ParameterVector g;
    restrictToActive(current_, active_, H, g);
    *cost = current_.cost;
    *normal = H;
    *gradient = g;
    return std::isfinite(current_.cost) && H.allFinite() && g.allFinite();
  }
  bool trialCost(const Eigen::VectorXd& step, double* cost) override {
    const ParameterVector parameter_step = step;
    candidate_ = applyStep(state_, parameter_step, max_readout_s_);
    applyShiftStep(candidate_, current_, parameter_step);
    trial_ = problem_.evaluate(candidate_, weights_, false);
    *cost = trial_.cost;
    return std::isfinite(trial_.cost);
  }
  bool accept(const Eigen::VectorXd& step) override {
    state_ = candidate_;
    weights_ = cauchyWeights(trial_.residual_norms_px, options_, nullptr);
    const bool small = std::abs(step(kOffset)) < 1e-6 && std::abs(step(kReadout)) < 1e-6 &&
                       step.segment<3>(kBias).norm() < 1e-5 && step.segment<3>(kRotation).norm() < 1e-6;
    quiet_steps_ = small ? quiet_steps_ + 1 : 0;
    return quiet_steps_ >= 2;
  }

 private:
  ReprojectionProblem& problem_;
  const ActiveParameters& active_;
  const CalibrationOptions& options_;
  double max_readout_s_;
  CalibrationState& state_;
  std::vector<double>& weights_;
  CalibrationEvaluation current_, trial_;
  CalibrationState candidate_;
  int quiet_steps_ = 0;
};

}  // namespace

Refinement refineCalibration(ReprojectionProblem& problem, const ActiveParameters& active,
                             const CalibrationOptions& options, double max_readout_s, CalibrationState& state) {
  Refinement refinement;
  const int n = static_cast<int>(std::count(active.begin(), active.end(), true));
  state.shifts.assign(problem.shiftBlockCount(), LensShiftCoefficients::Zero());
  CalibrationEvaluation current = problem.evaluate(state, {}, problem.shiftBlockCount() > 0);
  if (problem.shiftBlockCount() > 0) {
    // Start the lens shifts at their best fit to the coarse calibration.
    applyShiftStep(state, current, ParameterVector::Zero());
    current = problem.evaluate(state, {}, false);
  }
  refinement.initial_median_residual_px = median(current.residual_norms_px);
  refinement.weights = cauchyWeights(current.residual_norms_px, options, nullptr);
  if (n == 0) return refinement;
  CalibrationRefinementProblem linearised(problem, active, options, max_readout_s, state, refinement.weights);
  NonlinearLeastSquaresOptions solver;
  solver.max_iterations = options.max_iterations;
  solver.function_tolerance = 0.0;  // the problem's own test: the steps no longer matter
  // Light damping that falls fast: the coarse alignment starts the refinement near its minimum.
  solver.damping = {1e-3, 5.0, 10.0, 1e-9, 12};
  const NonlinearLeastSquaresReport report = minimiseLevenbergMarquardt(linearised, solver);
  // No step lowering the cost is a minimum to the damping's resolution: converged too. Each
  // iteration is a linearisation, the last one's included when no step was accepted from it.
  refinement.converged = report.termination == SolverTermination::kConverged ||
                         report.termination == SolverTermination::kNoProgress;
  refinement.iterations = report.iterations + (report.termination == SolverTermination::kNoProgress ? 1 : 0);
  return refinement;
}

CalibrationUncertainty estimateUncertainty(ReprojectionProblem& problem, const CalibrationState& state,
                                           const std::vector<double>& weights, const ActiveParameters& active,
                                           const CalibrationOptions& options) {
  CalibrationUncertainty out;
  const CalibrationEvaluation final_evaluation = problem.evaluate(state, weights, true);
  std::vector<ParameterVector> pair_scores;
  problem.evaluate(state, weights, true, &final_evaluation.shift_gain, &pair_scores);
  out.median_residual_px = median(final_evaluation.residual_norms_px);
  out.inlier_fraction =
      static_cast<double>(std::count_if(weights.begin(), weights.end(), [](double w) { return w > 0.5; })) /
      std::max<std::size_t>(weights.size(), 1);
  // The held values' own 1-sigma (0 = exact), per parameter.
  ParameterVector held_sigma;
  held_sigma(kOffset) = options.held_time_offset_sigma_s;
  held_sigma(kReadout) = options.held_readout_time_sigma_s;
  held_sigma.segment<3>(kBias).setConstant(options.held_gyro_bias_sigma_rad_s);
  held_sigma.segment<3>(kRotation).setConstant(options.held_rotation_sigma_rad);
  for (int i = 0; i < kParameterCount; ++i) {
    if (!active[i]) out.reported(i) = held_sigma(i);
  }
  const int n = static_cast<int>(std::count(active.begin(), active.end(), true));
  if (n == 0) return out;

  ParameterMatrix H;
  ParameterVector unused_gradient;
  restrictToActive(final_evaluation, active, H, unused_gradient);
  // Degrees of freedom: per track, less the parameters and the eliminated nuisances.
  const double nuisance = problem.shiftUnknownCount();
  // One component per track is left when the parallax is removed, and a direction per pair
  // is spent on it.
  const double components = removesParallax(options) ? 1.0 : 2.0;
  const double parallax = removesParallax(options) ? 2.0 * problem.pairCount() : 0.0;
  const double dof = std::max(components * final_evaluation.weight_sum - n - nuisance - parallax, 1.0);
  const double variance = final_evaluation.cost / dof;
  // A direction the data does not constrain has a (near) zero eigenvalue: its variance is
  // then effectively infinite, which the checks below turn into a refusal.
  // Scaled to a unit diagonal first, so that seconds and radians compare in the rank test.
  ParameterVector scale;
  for (int i = 0; i < kParameterCount; ++i) scale(i) = 1.0 / std::sqrt(std::max(H(i, i), 1e-300));
  const ParameterMatrix normalised = scale.asDiagonal() * H * scale.asDiagonal();
  // (SVD of the symmetric matrix: its singular vectors are its eigenvectors.)
  const Eigen::JacobiSVD<ParameterMatrix> svd(normalised, Eigen::ComputeFullU | Eigen::ComputeFullV);
  ParameterVector inverse_values;
  for (int i = 0; i < kParameterCount; ++i) {
    const double value = svd.singularValues()(i);
    inverse_values(i) = value > 1e-12 ? 1.0 / value : 1e30;
  }
  const ParameterMatrix H_inverse = scale.asDiagonal() * svd.matrixV() * inverse_values.asDiagonal() *
                                    svd.matrixU().transpose() * scale.asDiagonal();
  const ParameterMatrix covariance = variance * H_inverse;
  // Tracks of one moment share what the model misses (parallax of that moment's translation,
  // the lens shift's misfit, a tracking bias of that image content), so treating them as
  // independent overstates the information. The cluster-robust ("sandwich") covariance
  // H^-1 (sum_c s_c s_c^T) H^-1 over clusters of consecutive pairs (s_c the sum of their
  // scores) counts each stretch of the recording once; the larger of the two is reported.
  // What the model misses stays correlated for longer than 5 pairs when it comes from the scene
  // (the parallax of its layout under the hand's slow translation and pans lasts seconds): the
  // sandwich is formed for blocks of 5, 15 and 30 consecutive pairs and for sixths of the
  // recording, and each quantity takes the largest (a block length chosen conservatively, as in
  // a block bootstrap); a block length with fewer than 6 blocks is too noisy to count.
  ParameterVector sandwich_variance = ParameterVector::Zero();
  std::vector<std::size_t> block_lengths = {kPairsPerCluster, 3 * kPairsPerCluster, 6 * kPairsPerCluster,
                                            pair_scores.size() / 6};
  for (const std::size_t block : block_lengths) {
    if (block == 0 || pair_scores.size() / block < 6) continue;
    ParameterMatrix meat = ParameterMatrix::Zero();
    int clusters = 0;
    for (std::size_t start = 0; start < pair_scores.size(); start += block, ++clusters) {
      ParameterVector cluster = ParameterVector::Zero();
      for (std::size_t p = start; p < std::min(start + block, pair_scores.size()); ++p) cluster += pair_scores[p];
      for (int i = 0; i < kParameterCount; ++i) {
        if (!active[i]) cluster(i) = 0.0;
      }
      meat.noalias() += cluster * cluster.transpose();
    }
    const double small_sample = clusters > 1 ? clusters / (clusters - 1.0) : 1.0;
    const ParameterMatrix sandwich = small_sample * H_inverse * meat * H_inverse;
    sandwich_variance = sandwich_variance.cwiseMax(sandwich.diagonal());
  }
  for (int i = 0; i < kParameterCount; ++i) {
    if (active[i]) out.statistical(i) = std::sqrt(std::max({covariance(i, i), sandwich_variance(i), 0.0}));
  }
  // A held value known only to +-s moves the estimated ones by (d estimate / d held) s, to first
  // order: d x_active / d x_held = -H_aa^-1 H_ah, with H_aa^-1 the active block of H_inverse (the
  // held rows and columns of H were replaced by the identity, so the inverse is block diagonal).
  const ParameterMatrix& H_full = final_evaluation.H;
  for (int h = 0; h < kParameterCount; ++h) {
    if (active[h] || !(held_sigma(h) > 0.0)) continue;
    ParameterVector column = H_full.col(h);
    for (int i = 0; i < kParameterCount; ++i) {
      if (!active[i]) column(i) = 0.0;
    }
    const ParameterVector sensitivity = -(H_inverse * column);
    for (int i = 0; i < kParameterCount; ++i) {
      if (active[i]) out.from_held(i) = std::hypot(out.from_held(i), sensitivity(i) * held_sigma(h));
    }
  }
  // The reported sigma: the statistical one inflated for the correlation it still misses, and
  // what the recording shares as a whole added in quadrature (independent of the statistical
  // part, which only sees what varies). See CalibrationOptions::statistical_sigma_factor.
  ParameterVector systematic;
  systematic(kOffset) = options.systematic_time_offset_s;
  systematic(kReadout) = options.systematic_readout_time_s;
  systematic.segment<3>(kBias).setConstant(options.systematic_gyro_bias_rad_s);
  systematic.segment<3>(kRotation).setConstant(options.systematic_rotation_rad);
  for (int i = 0; i < kParameterCount; ++i) {
    if (active[i]) {
      out.reported(i) = std::hypot(std::hypot(options.statistical_sigma_factor * out.statistical(i), systematic(i)),
                                   out.from_held(i));
    }
  }
  return out;
}

std::vector<std::string> uncertaintyRefusals(const CalibrationResult::Sigmas& statistical,
                                             const CalibrationOptions& options, const std::string& rates_text,
                                             CalibrationResult::Refused& refused) {
  std::vector<std::string> refusals;
  // Under OIS the usual motion advice is not enough: the lens absorbs most pan and tilt.
  const std::string ois_advice =
      options.lens_shift == LensShiftHandling::kPerFrameShift
          ? " (with OIS the lens absorbs most of the pan and tilt: record the calibration protocol, 10 s "
            "or more turning the camera briskly about all three axes, roll about the lens included, "
            "facing a scene 4 m away or more; or hold the mount at a known value, e.g. calibrated with "
            "OIS off)"
          : "";
  // Refusals judge what this recording determines: the statistical sigma (the systematic term is
  // the same for every recording; see CalibrationOptions::max_time_offset_sigma_s).
  if (options.estimate_time_offset && statistical.time_offset_s > options.max_time_offset_sigma_s) {
    refused.time_offset = true;
    refusals.push_back(
        "time offset: statistical 1-sigma " + describeSeconds(statistical.time_offset_s) + " exceeds " +
        describeSeconds(options.max_time_offset_sigma_s) +
        ": the rotation rate hardly changes during the recording (a steady turn looks the same at any "
        "offset); shake the camera, so that its rate changes within fractions of a second" + ois_advice);
  }
  if (options.estimate_readout_time && statistical.readout_time_s > options.max_readout_time_sigma_s) {
    refused.readout_time = true;
    refusals.push_back(
        "readout time: statistical 1-sigma " + describeSeconds(statistical.readout_time_s) + " exceeds " +
        describeSeconds(options.max_readout_time_sigma_s) +
        ": the top and bottom rows move alike (it needs vertical image motion, i.e. tilt about the camera x "
        "axis, roll about the optical axis, or rates that change within a frame); tilt and roll the camera "
        "while recording, or hold the readout at its known value" + ois_advice);
  }
  if (options.estimate_rotation && statistical.rotation_rad.maxCoeff() > options.max_rotation_sigma_rad) {
    refused.rotation = true;
    std::ostringstream why;
    why << std::fixed << std::setprecision(3) << "IMU-camera rotation: statistical 1-sigma ("
        << statistical.rotation_rad(0) * kRadToDeg << ", " << statistical.rotation_rad(1) * kRadToDeg << ", "
        << statistical.rotation_rad(2) * kRadToDeg << ") deg about the camera x, y, z axes exceeds "
        << options.max_rotation_sigma_rad * kRadToDeg
        << " deg: it needs clear rotation about at least two axes (gyro RMS about its principal axes "
        << rates_text << "); turn the camera about all three axes, or hold the rotation at a known value"
        << ois_advice;
    refusals.push_back(why.str());
  }
  if (options.estimate_gyro_bias && statistical.gyro_bias_rad_s.maxCoeff() > options.max_gyro_bias_sigma_rad_s) {
    refused.gyro_bias = true;
    std::ostringstream why;
    why << std::scientific << std::setprecision(2) << "gyro bias: statistical 1-sigma "
        << statistical.gyro_bias_rad_s.maxCoeff() << " rad/s exceeds " << options.max_gyro_bias_sigma_rad_s
        << " rad/s: record longer or with more texture, or hold the bias" << ois_advice;
    refusals.push_back(why.str());
  }
  return refusals;
}

}  // namespace deep_ois
