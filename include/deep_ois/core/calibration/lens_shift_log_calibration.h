// The convention of a camera's lens-shift log (core/ois/lens_shift_log.h) estimated against the
// images: the log's clock offset, its scale, and its axis order and signs. Pure core: no ROS.
//
// Why from the images: a phone's OisSample x/y are in active-array pixels of the sensor's native
// orientation, and whether they say where the lens moved or where the image moved is not
// documented per device; a wrong sign doubles the error it should remove. The images say it.
//
// How: with the camera-IMU calibration known, the gyro gives every row patch's rotation homography
// H_i = K R_i K^-1. A track in patch i of pair (a, b) then shows p_b - H_i p_a = s(t_b,i) -
// s(t_a,i) to first order (the lens shift difference between the patch's capture times; undistorted
// pixels). The median over a patch's tracks is one observation d. For a candidate clock offset tau
// the log gives q = raw(t_b,i - tau) - raw(t_a,i - tau) (logged units); d = A q is linear in the
// 2x2 map A, solved by least squares. tau is searched on a grid, refined by a parabola; then A is
// snapped to scale x a signed axis permutation (the 8 candidates), which is the convention.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

struct LensShiftLogCalibrationOptions {
  int patch_count = 6;                  // row patches of the observations
  double max_abs_time_offset_s = 0.05;  // the log's clock offset is searched in [-this, +this]
  double search_step_s = 0.0005;        // grid step of that search
  double max_gap_s = 0.02;              // log samples further apart are a gap (not used)
  int min_tracks_per_patch = 4;         // fewer tracks in a patch: no observation there
  // Observations whose residual exceeds this many times the median residual are dropped before
  // the final fit (a moving object in one patch, a bad track cluster).
  double outlier_factor = 4.0;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

struct LensShiftLogCalibration {
  bool ok = false;
  std::string problem;                // why not ok: one sentence naming what is missing
  LensShiftLogConvention convention;  // the estimate (time_offset_s: camera = log stamp + it)
  Eigen::Matrix2d fitted_map = Eigen::Matrix2d::Zero();  // the free 2x2 fit A before snapping
  // How far A is from scale x signed permutation (Frobenius, relative): large = the log is not a
  // lens shift in image axes, or the tracks do not see it.
  double snap_error = 0.0;
  int observations = 0;             // (pair, patch) observations in the final fit
  double residual_rms_px = 0.0;     // of d - A q over them
  double lens_motion_rms_px = 0.0;  // RMS of the observed shift differences d (the signal)
};

// `log` as logged (stamps on the same time base as data.frame_stamps_s, the log's clock).
// Refuses (ok false, problem set) when the log is empty, too few observations are covered by it
// over the whole search range, or the lens barely moved. Throws std::invalid_argument for invalid
// options.
LensShiftLogCalibration calibrateLensShiftLog(const CalibrationData& data,
                                              const CameraImuCalibration& calibration,
                                              const std::vector<LensShiftLogSample>& log,
                                              const LensShiftLogCalibrationOptions& options = {});

}  // namespace deep_ois
