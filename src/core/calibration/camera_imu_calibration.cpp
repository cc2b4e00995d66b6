#include "deep_ois/core/calibration/camera_imu_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/calibration/calibration_reprojection_problem.h"
#include "deep_ois/core/calibration/camera_imu_calibration_stages.h"
#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/gyro/gyro_orientation_table.h"

namespace deep_ois {

const char* toString(LensShiftHandling handling) {
  switch (handling) {
    case LensShiftHandling::kNone: return "none";
    case LensShiftHandling::kPerFrameShift: return "per_frame_shift";
  }
  return "unknown";
}

std::string CalibrationOptions::validate() const {
  std::ostringstream why;
  if (!std::isfinite(time_offset_s) || std::abs(time_offset_s) > 10.0) {
    why << "time_offset_s must be within +-10 s (got " << time_offset_s << ")";
  } else if (!estimate_readout_time && !(readout_time_s >= 0.0 && readout_time_s <= 1.0)) {
    why << "readout_time_s must be in [0, 1] s when the readout is held (got " << readout_time_s << ")";
  } else if (!std::isfinite(readout_time_s) || readout_time_s > 1.0) {
    why << "readout_time_s must be at most 1 s, or negative for the default (got " << readout_time_s << ")";
  } else if (!gyro_bias_rad_s.allFinite()) {
    why << "gyro_bias_rad_s must be finite";
  } else if (!isProperRotation(imu_to_camera_rotation)) {
    why << "imu_to_camera_rotation must be a proper rotation matrix (orthonormal, det +1)";
  } else if (!(max_imu_gap_s > 0.0)) {
    why << "max_imu_gap_s must be positive (got " << max_imu_gap_s << ")";
  } else if (estimate_time_offset && !(max_abs_time_offset_s > 0.0 && max_abs_time_offset_s <= 5.0)) {
    why << "max_abs_time_offset_s must be in (0, 5] s (got " << max_abs_time_offset_s << ")";
  } else if (estimate_time_offset &&
             !(coarse_time_step_s > 0.0 && coarse_time_step_s <= max_abs_time_offset_s)) {
    why << "coarse_time_step_s must be in (0, max_abs_time_offset_s] (got " << coarse_time_step_s << ")";
  } else if (!std::isfinite(max_readout_time_s) || max_readout_time_s > 1.0) {
    why << "max_readout_time_s must be at most 1 s, or negative for the frame interval (got "
        << max_readout_time_s << ")";
  } else if (lens_shift_row_order < 0 || lens_shift_row_order > 3) {
    why << "lens_shift_row_order must be 0..3 (got " << lens_shift_row_order << ")";
  } else if (max_iterations < 1) {
    why << "max_iterations must be at least 1 (got " << max_iterations << ")";
  } else if (!(robust_scale_factor > 0.0) || !(min_robust_scale_px > 0.0)) {
    why << "robust_scale_factor and min_robust_scale_px must be positive";
  } else if (min_pairs < 1 || min_tracks_per_pair < 3) {
    why << "min_pairs must be >= 1 and min_tracks_per_pair >= 3";
  } else if (!(min_excitation_rate_rad_s >= 0.0)) {
    why << "min_excitation_rate_rad_s must be >= 0";
  } else if (!(systematic_time_offset_s >= 0.0) || !(systematic_readout_time_s >= 0.0) ||
             !(systematic_rotation_rad >= 0.0) || !(systematic_gyro_bias_rad_s >= 0.0) ||
             !std::isfinite(systematic_time_offset_s + systematic_readout_time_s + systematic_rotation_rad +
                            systematic_gyro_bias_rad_s)) {
    why << "the systematic_* uncertainties must be finite and >= 0";
  } else if (!(readout_boundary_s >= 0.0) || !std::isfinite(readout_boundary_s)) {
    why << "readout_boundary_s must be >= 0 seconds (0 = never)";
  } else if (!(statistical_sigma_factor >= 1.0 && statistical_sigma_factor <= 100.0)) {
    why << "statistical_sigma_factor must be in [1, 100] (got " << statistical_sigma_factor << ")";
  } else if (!(held_time_offset_sigma_s >= 0.0) || !(held_readout_time_sigma_s >= 0.0) ||
             !(held_rotation_sigma_rad >= 0.0) || !(held_gyro_bias_sigma_rad_s >= 0.0) ||
             !std::isfinite(held_time_offset_sigma_s + held_readout_time_sigma_s + held_rotation_sigma_rad +
                            held_gyro_bias_sigma_rad_s)) {
    why << "the held_*_sigma uncertainties must be finite and >= 0";
  } else if (!(max_time_offset_sigma_s > 0.0) || !(max_readout_time_sigma_s > 0.0) ||
             !(max_rotation_sigma_rad > 0.0) || !(max_gyro_bias_sigma_rad_s > 0.0)) {
    why << "the max_*_sigma limits must be positive";
  }
  return why.str();
}

KltOptions calibrationKltOptions() {
  KltOptions options;
  options.window_size_px = 11;
  return options;
}

std::string CalibrationResult::reason() const {
  std::string joined;
  for (const std::string& refusal : refusals) joined += (joined.empty() ? "" : "; ") + refusal;
  return joined;
}

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

std::string describeSeconds(double seconds) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << seconds * 1e3 << " ms";
  return out.str();
}

double medianFrameInterval(const std::vector<double>& stamps) {
  std::vector<double> intervals;
  for (std::size_t i = 1; i < stamps.size(); ++i) intervals.push_back(stamps[i] - stamps[i - 1]);
  return median(intervals);
}

void checkInput(const CalibrationData& data, const CalibrationOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("calibration options: " + problem);
  const std::string camera_problem = data.camera.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("calibration: camera: " + camera_problem);
  if (data.frame_stamps_s.size() < 2) {
    throw std::invalid_argument("calibration: needs at least two frame stamps");
  }
  for (std::size_t i = 1; i < data.frame_stamps_s.size(); ++i) {
    if (!(data.frame_stamps_s[i] > data.frame_stamps_s[i - 1])) {
      std::ostringstream why;
      why << std::setprecision(9) << "calibration: frame stamps must increase strictly, but frame " << i << " ("
          << data.frame_stamps_s[i] << " s) does not come after frame " << i - 1 << " ("
          << data.frame_stamps_s[i - 1] << " s)";
      throw std::invalid_argument(why.str());
    }
  }
  if (data.gyro.size() < 2) throw std::invalid_argument("calibration: needs gyro samples, got " + std::to_string(data.gyro.size()));
}

CalibrationResult calibrateOnce(const CalibrationData& data, const CalibrationOptions& options);

}  // namespace

CalibrationResult calibrateCameraImu(const CalibrationData& data, const CalibrationOptions& options) {
  CalibrationResult result = calibrateOnce(data, options);
  CameraImuCalibration& c = result.calibration;
  if (!result.converged && result.iterations >= options.max_iterations) {
    result.notes.push_back("the refinement stopped at its iteration cap (" + std::to_string(options.max_iterations) +
                           " iterations) without converging");
  }
  // A mount that wandered off the axis permutation the search found must earn it: a refinement
  // that does not lower the residual below that of the permutation held has not found a mount, it
  // has drifted along a weakly determined direction (and its 1-sigma, from the curvature there,
  // would be confidently wrong).
  if (options.estimate_rotation && result.iterations > 0) {
    result.nearest_permutation_index = nearestSignedAxisPermutation(c.imu_to_camera_rotation);
    const Eigen::Matrix3d& permutation =
        signedAxisPermutations()[static_cast<std::size_t>(result.nearest_permutation_index)];
    result.mount_from_permutation_deg = rotationAngleBetween(permutation, c.imu_to_camera_rotation) * kRadToDeg;
    const double sigma_deg = c.rotation_sigma_rad.maxCoeff() * kRadToDeg;
    if (result.mount_from_permutation_deg > std::max(2.0, 3.0 * sigma_deg)) {
      CalibrationOptions held = options;
      held.estimate_rotation = false;
      held.imu_to_camera_rotation = permutation;
      const CalibrationResult at_permutation = calibrateOnce(data, held);
      result.seconds += at_permutation.seconds;
      std::ostringstream why;
      why << std::fixed << std::setprecision(3) << "mount: the refinement ended "
          << std::setprecision(1) << result.mount_from_permutation_deg << " deg from the nearest axis permutation"
          << (result.converged ? "" : " without converging (iteration cap " + std::to_string(options.max_iterations) + ")")
          << ", with a 1-sigma of " << std::setprecision(2) << sigma_deg << " deg, but holding that permutation fits ";
      // Unconverged, the refined mount is where the iteration cap stopped a drift, whatever its
      // residual: a mount off the axes must be a converged minimum that fits better.
      const bool fits_as_well = at_permutation.median_residual_px <= 1.01 * result.median_residual_px;
      if (fits_as_well || !result.converged) {
        why << (fits_as_well ? "as well" : "only " + std::to_string(static_cast<int>(std::lround(
                                                100.0 * (at_permutation.median_residual_px / result.median_residual_px - 1.0)))) +
                                                " % worse")
            << " (median residual " << std::setprecision(3) << at_permutation.median_residual_px << " px against "
            << result.median_residual_px << " px)" << (fits_as_well ? "" : " and the refinement did not converge")
            << ": the data do not determine the mount beyond the permutation, so the refined mount and its "
               "1-sigma are not to be trusted. If the IMU is mounted along the camera's axes (a phone), hold it: "
               "--rotation ";
        for (int i = 0; i < 9; ++i) why << (i ? "," : "") << static_cast<int>(std::lround(permutation(i / 3, i % 3)));
        result.refusals.push_back(why.str());
        result.refused.rotation = true;
        result.status = CalibrationStatus::kRefused;
      } else {
        why << "worse (median residual " << std::setprecision(3) << at_permutation.median_residual_px << " px against "
            << result.median_residual_px << " px): the mount is off the camera's axes";
        result.notes.push_back(why.str());
      }
    }
  }
  if (!options.estimate_readout_time || !(options.readout_boundary_s > 0.0) ||
      !(c.readout_time_s < options.readout_boundary_s)) {
    return result;
  }
  // At the readout's lower bound: the other answer, a global shutter, widens the intervals.
  CalibrationOptions held = options;
  held.estimate_readout_time = false;
  held.readout_time_s = 0.0;
  const CalibrationResult global = calibrateOnce(data, held);
  const double offset_shift_s = c.time_offset_s - global.calibration.time_offset_s;
  c.time_offset_sigma_s = std::hypot(c.time_offset_sigma_s, offset_shift_s);
  c.readout_time_sigma_s = std::max(c.readout_time_sigma_s, c.readout_time_s);
  std::ostringstream note;
  note << std::fixed << std::setprecision(3) << "readout " << c.readout_time_s * 1e3
       << " ms is at its lower bound: with the readout held at 0 (a global shutter) the offset is "
       << global.calibration.time_offset_s * 1e3 << " ms; the reported intervals hold both (offset +- "
       << c.time_offset_sigma_s * 1e3 << " ms, readout +- " << c.readout_time_sigma_s * 1e3
       << " ms). For a global-shutter camera pass --readout 0";
  result.notes.push_back(note.str());
  result.seconds += global.seconds;
  return result;
}

namespace {

// One calibration: the four stages in turn (camera_imu_calibration_stages.h).
CalibrationResult calibrateOnce(const CalibrationData& data, const CalibrationOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  checkInput(data, options);
  CalibrationResult result;
  auto finish = [&]() -> CalibrationResult {
    result.status = result.refusals.empty() ? CalibrationStatus::kOk : CalibrationStatus::kRefused;
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return result;
  };

  const ImuSampleBuffer gyro = bufferOf(data.gyro);
  const double frame_interval_s = medianFrameInterval(data.frame_stamps_s);
  const double max_readout_s = options.max_readout_time_s >= 0.0 ? options.max_readout_time_s : frame_interval_s;
  const double initial_readout_s = options.readout_time_s >= 0.0 ? std::min(options.readout_time_s, max_readout_s)
                                                                  : 0.5 * max_readout_s;
  const double focal_px = 0.5 * (data.camera.K()(0, 0) + data.camera.K()(1, 1));

  std::vector<PreparedPair> pairs = preparePairs(data, options.min_tracks_per_pair);
  if (static_cast<int>(pairs.size()) < options.min_pairs) {
    std::ostringstream why;
    why << "calibration: only " << pairs.size() << " of " << data.pairs.size() << " frame pairs have at least "
        << options.min_tracks_per_pair << " tracks; at least " << options.min_pairs
        << " such pairs are needed (more frames, more texture)";
    throw std::invalid_argument(why.str());
  }

  // 1. Coarse, global stage: offset grid x 24 signed axis permutations.
  IntegrationOptions zero_bias;
  zero_bias.interpolation = options.interpolation;
  zero_bias.max_sample_gap_s = options.max_imu_gap_s;
  const GyroOrientationTable coarse_table(gyro, zero_bias);
  const CoarseStage coarse = runCoarseStage(pairs, coarse_table, options, initial_readout_s, focal_px);
  result.coarse_time_offset_s = coarse.alignment.time_offset_s;
  result.coarse_permutation_index = coarse.alignment.permutation_index;
  CalibrationState state = coarse.start;

  // 2. Motion prerequisites. Too little motion for any quantity: refused, with the coarse stage's
  // values as the (untrusted) calibration so that the caller still sees what was found.
  const MotionCheck motion = checkMotionPrerequisites(data, coarse.pairs, state, options, max_readout_s, focal_px);
  result.rate_rms_rad_s = motion.rate_rms_rad_s;
  result.median_image_rotation_px = motion.median_image_rotation_px;
  if (!motion.unobservable.empty()) {
    result.refusals.push_back(motion.unobservable);
    result.refused.motion = true;
    result.calibration.time_offset_s = state.time_offset_s;
    result.calibration.readout_time_s = state.readout_time_s;
    result.calibration.gyro_bias_rad_s = state.bias;
    result.calibration.imu_to_camera_rotation = state.R_cam_imu;
    return finish();
  }
  if (!motion.rotation_unobservable.empty()) {
    result.refusals.push_back(motion.rotation_unobservable);
    result.refused.rotation = true;
  }

  // 3. Continuous refinement, on the pairs the gyro covers around the coarse offset (the
  // refinement moves it by milliseconds).
  std::vector<PreparedPair> refined_pairs;
  for (PreparedPair& pair : pairs) {
    const double margin_s = 0.05;
    if (coarse_table.coverage(pair.stamp_a_s + state.time_offset_s - margin_s,
                              pair.stamp_b_s + state.time_offset_s + max_readout_s + margin_s).ok()) {
      refined_pairs.push_back(std::move(pair));
    }
  }
  if (static_cast<int>(refined_pairs.size()) < options.min_pairs) {
    std::ostringstream why;
    why << "calibration: the gyro covers only " << refined_pairs.size() << " of the " << pairs.size()
        << " usable frame pairs at the time offset found (" << describeSeconds(state.time_offset_s) << "); at least "
        << options.min_pairs << " are needed";
    throw std::invalid_argument(why.str());
  }
  ReprojectionProblem problem(refined_pairs, gyro, data.camera.K(), options.interpolation, options.max_imu_gap_s,
                              options.lens_shift, options.lens_shift_row_order, removesParallax(options));
  result.pairs_used = static_cast<int>(refined_pairs.size());
  result.tracks_used = static_cast<int>(problem.trackCount());
  const ActiveParameters active = activeParameters(options);
  const Refinement refinement = refineCalibration(problem, active, options, max_readout_s, state);
  result.iterations = refinement.iterations;
  result.converged = refinement.converged;
  result.initial_median_residual_px = refinement.initial_median_residual_px;

  // 4. Uncertainty and observability.
  const CalibrationUncertainty uncertainty = estimateUncertainty(problem, state, refinement.weights, active, options);
  result.median_residual_px = uncertainty.median_residual_px;
  result.inlier_fraction = uncertainty.inlier_fraction;
  CameraImuCalibration& calibration = result.calibration;
  calibration.time_offset_s = state.time_offset_s;
  calibration.readout_time_s = state.readout_time_s;
  calibration.gyro_bias_rad_s = state.bias;
  calibration.imu_to_camera_rotation = state.R_cam_imu;
  using namespace calibration_parameter;
  result.statistical.time_offset_s = uncertainty.statistical(kOffset);
  result.statistical.readout_time_s = uncertainty.statistical(kReadout);
  result.statistical.gyro_bias_rad_s = uncertainty.statistical.segment<3>(kBias);
  result.statistical.rotation_rad = uncertainty.statistical.segment<3>(kRotation);
  calibration.time_offset_sigma_s = uncertainty.reported(kOffset);
  calibration.readout_time_sigma_s = uncertainty.reported(kReadout);
  calibration.gyro_bias_sigma_rad_s = uncertainty.reported.segment<3>(kBias);
  calibration.rotation_sigma_rad = uncertainty.reported.segment<3>(kRotation);
  for (std::string& refusal : uncertaintyRefusals(result.statistical, options, motion.rates_text, result.refused)) {
    result.refusals.push_back(std::move(refusal));
  }
  return finish();
}

}  // namespace

std::vector<double> trackResidualsPx(const CalibrationData& data, const CameraImuCalibration& calibration,
                                     RateInterpolation interpolation) {
  const std::string camera_problem = data.camera.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("track residuals: camera: " + camera_problem);
  if (data.gyro.size() < 2) throw std::invalid_argument("track residuals: needs gyro samples");
  const ImuSampleBuffer gyro = bufferOf(data.gyro);
  IntegrationOptions integration;
  integration.interpolation = interpolation;
  integration.gyro_bias_rad_s = calibration.gyro_bias_rad_s;
  const GyroOrientationTable table(gyro, integration);
  std::vector<PreparedPair> pairs;
  for (PreparedPair& pair : preparePairs(data, 1)) {
    if (table.coverage(pair.stamp_a_s + calibration.time_offset_s,
                       pair.stamp_b_s + calibration.time_offset_s + calibration.readout_time_s).ok()) {
      pairs.push_back(std::move(pair));
    }
  }
  CalibrationState state;
  state.time_offset_s = calibration.time_offset_s;
  state.readout_time_s = calibration.readout_time_s;
  state.bias = calibration.gyro_bias_rad_s;
  state.R_cam_imu = calibration.imu_to_camera_rotation;
  ReprojectionProblem problem(pairs, gyro, data.camera.K(), interpolation, integration.max_sample_gap_s,
                              LensShiftHandling::kNone, 0, false);
  return problem.evaluate(state, {}, false).residual_norms_px;
}

}  // namespace deep_ois
