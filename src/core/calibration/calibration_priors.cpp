#include "deep_ois/core/calibration/calibration_priors.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// Which priors are held.
struct Holds {
  bool readout_time = false;
  bool rotation = false;
  bool gyro_bias = false;
};

CalibrationOptions withHolds(const CalibrationOptions& base, const CalibrationPriors& priors, const Holds& holds) {
  CalibrationOptions options = base;
  if (holds.readout_time) {
    options.estimate_readout_time = false;
    options.readout_time_s = *priors.readout_time_s;
    options.held_readout_time_sigma_s = priors.readout_time_sigma_s;
  }
  if (holds.rotation) {
    options.estimate_rotation = false;
    options.imu_to_camera_rotation = *priors.imu_to_camera_rotation;
    options.held_rotation_sigma_rad = priors.rotation_sigma_rad;
  }
  if (holds.gyro_bias) {
    options.estimate_gyro_bias = false;
    options.gyro_bias_rad_s = *priors.gyro_bias_rad_s;
    options.held_gyro_bias_sigma_rad_s = priors.gyro_bias_sigma_rad_s;
  }
  return options;
}

std::string permutationFlag(int index) {
  const Eigen::Matrix3d& P = signedAxisPermutations()[static_cast<std::size_t>(index)];
  std::ostringstream out;
  out << "--rotation ";
  for (int i = 0; i < 9; ++i) out << (i ? "," : "") << static_cast<int>(std::lround(P(i / 3, i % 3)));
  return out.str();
}

// Why the recording does not determine a quantity, from the refused calibration's figures.
std::string readoutWhy(const CalibrationResult& result, const CalibrationOptions& options) {
  std::ostringstream why;
  why << std::fixed << std::setprecision(3) << "its statistical 1-sigma " << result.statistical.readout_time_s * 1e3
      << " ms exceeds " << options.max_readout_time_sigma_s * 1e3 << " ms";
  return why.str();
}

std::string rotationWhy(const CalibrationResult& result, const CalibrationOptions& options) {
  std::ostringstream why;
  why << std::fixed << std::setprecision(3);
  if (result.rate_rms_rad_s(1) < options.min_excitation_rate_rad_s) {
    why << "the motion is about one axis only";
  } else if (result.iterations > 0 && result.nearest_permutation_index >= 0 &&
             result.mount_from_permutation_deg > 2.0) {
    why << "the refined mount drifted " << std::setprecision(1) << result.mount_from_permutation_deg
        << " deg off the axis permutation without fitting better";
  } else {
    why << "its statistical 1-sigma " << result.statistical.rotation_rad.maxCoeff() * kRadToDeg << " deg exceeds "
        << options.max_rotation_sigma_rad * kRadToDeg << " deg";
  }
  return why.str();
}

std::string biasWhy(const CalibrationResult& result, const CalibrationOptions& options) {
  std::ostringstream why;
  why << std::scientific << std::setprecision(2) << "its statistical 1-sigma "
      << result.statistical.gyro_bias_rad_s.maxCoeff() << " rad/s exceeds " << options.max_gyro_bias_sigma_rad_s
      << " rad/s";
  return why.str();
}

}  // namespace

std::string CalibrationPriors::validate() const {
  std::ostringstream why;
  if (readout_time_s && !(*readout_time_s >= 0.0 && *readout_time_s <= 1.0)) {
    why << "the readout prior must be in [0, 1] s (got " << *readout_time_s << ")";
  } else if (!(readout_time_sigma_s >= 0.0) || !std::isfinite(readout_time_sigma_s)) {
    why << "the readout prior's 1-sigma must be finite and >= 0 s";
  } else if (imu_to_camera_rotation && !isProperRotation(*imu_to_camera_rotation)) {
    why << "the mount prior must be a proper rotation matrix (orthonormal, det +1)";
  } else if (!(rotation_sigma_rad >= 0.0) || !std::isfinite(rotation_sigma_rad)) {
    why << "the mount prior's 1-sigma must be finite and >= 0 rad";
  } else if (gyro_bias_rad_s && !gyro_bias_rad_s->allFinite()) {
    why << "the gyro bias prior must be finite";
  } else if (!(gyro_bias_sigma_rad_s >= 0.0) || !std::isfinite(gyro_bias_sigma_rad_s)) {
    why << "the gyro bias prior's 1-sigma must be finite and >= 0 rad/s";
  }
  return why.str();
}

const char* toString(CalibrationValueSource source) {
  switch (source) {
    case CalibrationValueSource::kData: return "data";
    case CalibrationValueSource::kPrior: return "prior";
    case CalibrationValueSource::kCaller: return "held";
  }
  return "unknown";
}

PriorCalibration calibrateWithPriors(const CalibrationData& data, const CalibrationOptions& options,
                                     const CalibrationPriors& priors) {
  const std::string problem = priors.validate();
  if (!problem.empty()) throw std::invalid_argument("calibration priors (" + priors.source + "): " + problem);
  PriorCalibration out;
  auto run = [&](const CalibrationOptions& run_options) {
    ++out.calibrations;
    CalibrationResult run_result = calibrateCameraImu(data, run_options);
    out.seconds += run_result.seconds;
    return run_result;
  };
  // The caller's holds stay; a prior only stands in for what the caller left to the data.
  CalibrationOptions base = options;
  const bool readout_prior = priors.readout_time_s && options.estimate_readout_time;
  const bool rotation_prior = priors.imu_to_camera_rotation && options.estimate_rotation;
  const bool bias_prior = priors.gyro_bias_rad_s && options.estimate_gyro_bias;
  // The logged readout is a better start than half the frame interval.
  if (readout_prior && options.readout_time_s < 0.0) base.readout_time_s = *priors.readout_time_s;
  const int prior_permutation =
      priors.imu_to_camera_rotation ? nearestSignedAxisPermutation(*priors.imu_to_camera_rotation) : -1;

  Holds holds;
  CalibrationResult result = run(base);
  out.refused_when_free = result.refused;
  bool mount_conflict_said = false;
  for (int round = 0; round < 3 && !result.ok() && !result.refused.motion; ++round) {
    const CalibrationOptions& tried = withHolds(base, priors, holds);
    bool changed = false;
    std::ostringstream decision;
    decision << std::fixed << std::setprecision(3);
    if (result.refused.readout_time && readout_prior && !holds.readout_time) {
      holds.readout_time = changed = true;
      decision.str("");
      decision << "readout time: " << priors.readout_time_s.value() * 1e3 << " ms +- "
               << priors.readout_time_sigma_s * 1e3 << " ms from " << priors.source
               << ", held: the recording does not determine it (" << readoutWhy(result, tried) << ")";
      out.decisions.push_back(decision.str());
    }
    if (result.refused.rotation && rotation_prior && !holds.rotation && !mount_conflict_said) {
      // A prior the motion contradicts is not quietly held: when the data's own search (or
      // refinement) lands on another permutation, the stated mount must fit as well as what the
      // data found (median residual within 1 %, the rule of the mount check), or it is refused,
      // naming both. (With motion about one axis, several permutations fit alike.)
      const int data_permutation =
          result.nearest_permutation_index >= 0 ? result.nearest_permutation_index : result.coarse_permutation_index;
      bool consistent = data_permutation < 0 || data_permutation == prior_permutation;
      double held_residual_px = 0.0;
      if (!consistent && result.iterations > 0) {
        Holds mount_only = holds;
        mount_only.rotation = true;
        held_residual_px = run(withHolds(base, priors, mount_only)).median_residual_px;
        consistent = held_residual_px <= 1.01 * result.median_residual_px;
      }
      if (consistent) {
        holds.rotation = changed = true;
        decision.str("");
        decision << "IMU-camera rotation: from " << priors.source << " (" << permutationFlag(prior_permutation)
                 << ", +- " << std::setprecision(2) << priors.rotation_sigma_rad * kRadToDeg
                 << " deg per axis), held: the recording does not refine it (" << rotationWhy(result, tried) << ")";
        out.decisions.push_back(decision.str());
      } else {
        mount_conflict_said = true;
        decision.str("");
        decision << "IMU-camera rotation: not held at " << priors.source << "'s mount ("
                 << permutationFlag(prior_permutation) << "): the recording's axis search picks "
                 << permutationFlag(data_permutation) << " instead";
        if (held_residual_px > 0.0) {
          decision << ", and the stated mount fits worse (median residual " << std::setprecision(3)
                   << held_residual_px << " px against " << result.median_residual_px << " px)";
        }
        decision << "; pass the one you trust";
        out.decisions.push_back(decision.str());
      }
    }
    if (result.refused.gyro_bias && bias_prior && !holds.gyro_bias) {
      holds.gyro_bias = changed = true;
      decision.str("");
      decision << std::scientific << std::setprecision(2) << "gyro bias: " << priors.gyro_bias_rad_s->norm()
               << " rad/s (the bias " << priors.source << " subtracts; 0 = none) +- " << priors.gyro_bias_sigma_rad_s
               << " rad/s, held: the recording does not determine it (" << biasWhy(result, tried) << ")";
      out.decisions.push_back(decision.str());
    }
    if (!changed) break;
    result = run(withHolds(base, priors, holds));
  }

  // Estimate what the data supports: a quantity refused beside others may be determined once they
  // are held. Each held prior is released in turn, and stays released when still accepted.
  if (result.ok()) {
    auto release = [&](bool Holds::*which, const char* name) {
      if (!(holds.*which)) return;
      Holds trial_holds = holds;
      trial_holds.*which = false;
      CalibrationResult trial = run(withHolds(base, priors, trial_holds));
      if (!trial.ok()) return;
      holds = trial_holds;
      result = std::move(trial);
      out.decisions.push_back(std::string(name) + ": estimated after all, accepted once the others are held");
    };
    release(&Holds::gyro_bias, "gyro bias");
    release(&Holds::readout_time, "readout time");
    release(&Holds::rotation, "IMU-camera rotation");
  }

  out.options = withHolds(base, priors, holds);
  out.result = std::move(result);
  auto source = [](bool estimated, bool held_prior) {
    return held_prior ? CalibrationValueSource::kPrior
                      : estimated ? CalibrationValueSource::kData : CalibrationValueSource::kCaller;
  };
  out.time_offset = source(options.estimate_time_offset, false);
  out.readout_time = source(options.estimate_readout_time, holds.readout_time);
  out.gyro_bias = source(options.estimate_gyro_bias, holds.gyro_bias);
  out.rotation = source(options.estimate_rotation, holds.rotation);

  // An estimate that disagrees with the stated value by more than 3 combined sigma is said: the
  // metadata (or the scene) is not what it seems.
  const CameraImuCalibration& c = out.result.calibration;
  if (out.result.ok() && readout_prior && out.readout_time == CalibrationValueSource::kData) {
    const double difference_s = c.readout_time_s - *priors.readout_time_s;
    const double combined_s = std::hypot(c.readout_time_sigma_s, priors.readout_time_sigma_s);
    if (std::abs(difference_s) > 3.0 * combined_s) {
      std::ostringstream note;
      note << std::fixed << std::setprecision(3) << "readout time: the estimate " << c.readout_time_s * 1e3
           << " ms differs from " << priors.source << "'s " << *priors.readout_time_s * 1e3 << " ms by "
           << difference_s * 1e3 << " ms, more than 3 x their combined 1-sigma (" << combined_s * 1e3 << " ms)";
      out.decisions.push_back(note.str());
    }
  }
  if (out.result.ok() && rotation_prior && out.rotation == CalibrationValueSource::kData) {
    const double angle_rad = rotationAngleBetween(c.imu_to_camera_rotation, *priors.imu_to_camera_rotation);
    const double combined_rad = std::hypot(c.rotation_sigma_rad.maxCoeff(), priors.rotation_sigma_rad);
    if (angle_rad > 3.0 * combined_rad) {
      std::ostringstream note;
      note << std::fixed << std::setprecision(2) << "IMU-camera rotation: the estimate is " << angle_rad * kRadToDeg
           << " deg from " << priors.source << "'s mount, more than 3 x their combined 1-sigma ("
           << combined_rad * kRadToDeg << " deg)";
      out.decisions.push_back(note.str());
    }
  }
  return out;
}

}  // namespace deep_ois
