// The camera-IMU calibration with what a recording already states: a phone logger's metadata
// gives the rolling-shutter readout (Android's rolling-shutter skew) and the IMU-to-camera mount
// (the Android axis permutation for the sensor orientation), and its gyro has the phone's own
// drift estimate removed. These are priors: each is held at its stated value, with its 1-sigma,
// only when the recording cannot determine it itself (its statistical 1-sigma exceeds the
// acceptance limit, or the mount drifts off its axis permutation); everything the data supports is
// estimated. The result says, per quantity, where its value came from and why. Pure Eigen.
//
// The procedure (calibrateWithPriors):
//  1. Calibrate with everything estimated that the caller does not hold (the readout starting
//     from its prior).
//  2. While refused: hold every refused quantity that has a prior at that prior, and calibrate
//     again. A mount prior is held only when it is the axis permutation the data's own search
//     picks (a mount the motion contradicts is refused, naming both).
//  3. Once accepted: release each held prior in turn and keep it estimated when the calibration
//     is still accepted (a quantity refused beside others can be determined once they are held).
// A motion refusal (the camera hardly rotates) ends it: no prior makes such a recording
// calibrate the time offset.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/camera_imu_calibration.h"

namespace deep_ois {

struct CalibrationPriors {
  // Where the priors come from, for the sentences (e.g. "rec.gyro_flow.yaml").
  std::string source = "the metadata";
  // The logged readout, seconds, and its 1-sigma. Default: the readout's acceptance limit
  // (CalibrationOptions::max_readout_time_sigma_s), i.e. trusted as much as the least certain
  // readout calibrate accepts from data.
  std::optional<double> readout_time_s;
  double readout_time_sigma_s = 0.25e-3;
  // The stated mount (R_cam_imu) and its 1-sigma per camera axis, radians. Default 1 degree: a
  // phone's IMU is placed along the board's axes, to an accuracy the metadata does not state.
  std::optional<Eigen::Matrix3d> imu_to_camera_rotation;
  double rotation_sigma_rad = 3.14159265358979323846 / 180.0;
  // The gyro bias the recording's gyro flow parameters subtract (zero for a phone logger's gyro,
  // which has the phone's own drift estimate removed), held when the data cannot determine it,
  // with its 1-sigma per IMU axis (default: the bias's acceptance limit).
  std::optional<Eigen::Vector3d> gyro_bias_rad_s;
  double gyro_bias_sigma_rad_s = 2e-3;

  bool empty() const { return !readout_time_s && !imu_to_camera_rotation && !gyro_bias_rad_s; }
  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Where a calibrated quantity's value came from.
enum class CalibrationValueSource {
  kData,      // estimated from the recording
  kPrior,     // held at the prior (the recording could not determine it)
  kCaller,    // held by the caller (CalibrationOptions::estimate_* false)
};

const char* toString(CalibrationValueSource source);

struct PriorCalibration {
  // The final calibration (accepted, or the last refused attempt).
  CalibrationResult result;
  // The options of that calibration: what was held, at what, with which 1-sigma.
  CalibrationOptions options;
  CalibrationValueSource time_offset = CalibrationValueSource::kData;
  CalibrationValueSource readout_time = CalibrationValueSource::kData;
  CalibrationValueSource gyro_bias = CalibrationValueSource::kData;
  CalibrationValueSource rotation = CalibrationValueSource::kData;
  // One sentence per decision: why a prior was held (the refusal it answered), released, not
  // held, or disagrees with the estimate.
  std::vector<std::string> decisions;
  int calibrations = 0;  // calibrateCameraImu() runs it took
  double seconds = 0.0;  // their wall time together
  // Whether the refusal of the first, free calibration named each quantity.
  CalibrationResult::Refused refused_when_free;
};

// Calibrates with `options` (its holds are the caller's), using `priors` as above. Throws as
// calibrateCameraImu() does, and std::invalid_argument for invalid priors.
PriorCalibration calibrateWithPriors(const CalibrationData& data, const CalibrationOptions& options,
                                     const CalibrationPriors& priors);

}  // namespace deep_ois
