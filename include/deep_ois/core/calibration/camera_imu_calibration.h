// Camera-IMU calibration from point tracks and the gyro stream: the camera-IMU time offset, the
// rolling-shutter readout time, a constant gyro bias and the IMU-to-camera rotation, jointly, with
// no calibration target. Pure Eigen + OpenCV: no ROS. Plain data in, so a rosbag, a phone
// recording or synthetic tracks all go through the same estimator.
//
// Model (the gyro flow's, conventions in the README): a point tracked from row v_a of frame a to
// row v_b of frame b is captured at IMU times
//     t_a = stamp_a + time_offset + readout_time * v_a / height,   t_b likewise,
// and the gyro rotation between them, R_b_a = R_cam_imu (R_imu(t_a)^T R_imu(t_b))^T R_cam_imu^T
// with the bias subtracted from every sample, predicts x_b = K R_b_a K^-1 x_a (undistorted pixels).
// Every point has its own capture times, so the residual is exact for any rolling shutter, not a
// per-patch approximation.
//
// Stages (camera_imu_calibration_stages.h, the model in calibration_reprojection_problem.h):
//  1. Coarse, global (camera_imu_coarse_alignment.h): a rotation fitted to each pair's tracks is
//     compared with the gyro rotation over a grid of time offsets and all 24 signed axis
//     permutations; the best cell, refined by Procrustes, starts stage 2. No initial guess needed.
//  2. Continuous refinement: Levenberg-Marquardt on the reprojection residuals of all tracks over
//     (time offset, readout, bias, rotation), analytic Jacobians, Cauchy loss by iteratively
//     reweighted least squares (moving objects and bad tracks get down-weighted). The parallax
//     of camera translation is removed per track (see eliminate_parallax).
//  3. Uncertainty: the larger of sigma^2 (J^T W J)^-1 (sigma^2 the weighted residual variance)
//     and the cluster-robust covariance over stretches of consecutive pairs, which counts what
//     the tracks of one moment share (parallax, a lens-shift misfit) once. A quantity whose
//     uncertainty exceeds its limit, or whose motion prerequisite is missing, is refused with the
//     reason and the remedy.
//
// OIS cameras (LensShiftHandling::kPerFrameShift): the stabilizer shifts the lens against pan and
// tilt (never roll about the optical axis), so the images move less than the gyro says and a fit
// that ignores it is off by milliseconds and tens of degrees. The lens shift acts as a
// principal-point shift, so the model becomes x_b = pi(K R_b_a K^-1 (x_a - s_a(row))) + s_b(row'),
// with s_k the shift of frame k as a polynomial of the row (the lens moves during the readout).
// Every frame's shift is shared by the two pairs it belongs to and is estimated jointly with the
// calibration, eliminated by a sparse Schur complement at each iteration (as landmarks in bundle
// adjustment), under a prior that keeps the lens within a few pixels of its centre (its stroke).
// Subtracting the shift before the rotation matters: a translation added after it would miss the
// perspective of a pan about a shifted principal point, which biases the mount by about
// shift / focal (a degree for 4 px at 230 px). What the shifts cannot absorb pins the
// calibration: roll about the optical axis, the perspective (keystone) part of pan and tilt, and
// pans too slow or too large for the lens. That is far less signal than a fixed lens gives, and
// the recording has to supply it (the calibration protocol, README "Calibration"): brisk turns
// about all three axes, because roll is the one rotation the lens never cancels and so carries the
// timing and the tilt of the mount, and a scene 4 m away or more, because what the shifts leave is
// the perspective of pan and tilt, which the parallax of near objects mimics. Recorded so (10 s),
// 24 of 24 simulator OIS bags are within 0.5 ms / 0.5 ms / 0.5 degree; a hand-held shot (weak roll,
// near objects, 5 s) gives 3 of 24, and the estimator refuses most of those. Otherwise hold the
// rotation (calibrate --rotation) from a recording with OIS off or from CAD.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/orientation_integrator.h"

namespace deep_ois {

// Tracks between two frames of the recording (usually consecutive ones).
struct CalibrationPair {
  int frame_a = 0;  // index into CalibrationData::frame_stamps_s (the earlier frame)
  int frame_b = 1;
  std::vector<FeatureMatch> matches;  // raw (distorted) pixels, a -> b
};

struct CalibrationData {
  std::vector<ImuSample> gyro;         // IMU frame, IMU clock, strictly increasing stamps
  std::vector<double> frame_stamps_s;  // camera clock: capture of each frame's first row
  CameraModel camera;                  // image size, K, distortion
  std::vector<CalibrationPair> pairs;
};

enum class LensShiftHandling {
  kNone,          // a fixed lens (no OIS, or OIS off)
  kPerFrameShift,  // OIS: a lens shift per frame (polynomial of the row) estimated alongside
};

const char* toString(LensShiftHandling handling);

struct CalibrationOptions {
  // Quantities to estimate; the others are held at the values below.
  bool estimate_time_offset = true;
  bool estimate_readout_time = true;
  bool estimate_gyro_bias = true;
  bool estimate_rotation = true;
  // Held values, or starting points: the time offset and rotation start from the coarse stage
  // when estimated; the readout starts here (negative = half the median frame interval); the
  // bias starts from the coarse stage's estimate when estimated.
  double time_offset_s = 0.0;  // IMU time = camera stamp + time_offset_s
  double readout_time_s = -1.0;
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  // IMU frame
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();  // R_cam_imu
  // 1-sigma of each held value (0 = exact; ignored while the quantity is estimated): a value
  // known to within +-s, e.g. a phone's logged readout. The held quantity reports it as its
  // 1-sigma, and every estimated quantity adds in quadrature what s moves it by (to first order,
  // through the normal equations). It does not enter the statistical sigma the refusals judge.
  double held_time_offset_sigma_s = 0.0;
  double held_readout_time_sigma_s = 0.0;
  double held_gyro_bias_sigma_rad_s = 0.0;  // per IMU axis
  double held_rotation_sigma_rad = 0.0;     // per camera axis

  LensShiftHandling lens_shift = LensShiftHandling::kNone;
  // Remove the parallax of camera translation (fixed lens only): per pair a translation direction
  // is fitted and every track keeps only its residual across its own parallax direction (depth no
  // longer matters). Hand-held recordings translate by millimetres per frame, which near objects
  // turn into tenths of a pixel: enough to bias the rotation by most of a degree. Costs half the
  // residual components; turn it off only for a camera that truly only rotates. Not used with
  // kPerFrameShift: the lens shifts already absorb the common part of the parallax, and what is
  // left to fit under OIS is too weak to give up a component of every track (measured worse).
  bool eliminate_parallax = true;
  // With kPerFrameShift: each frame's shift is a polynomial of the row of this order (0 = a
  // translation, 1 = + a translation growing with the row, ...; at most 3). The cubic follows the
  // lens through a long readout (33 ms: readout error -1.25 ms with the quadratic, -0.24 ms with
  // the cubic on a simulator bag).
  int lens_shift_row_order = 3;
  RateInterpolation interpolation = RateInterpolation::kLinear;
  double max_imu_gap_s = 0.05;  // a pair whose interval crosses a longer gap is not used

  // Coarse stage: the offset grid spans [-max_abs_time_offset_s, +max_abs_time_offset_s].
  double max_abs_time_offset_s = 0.2;
  double coarse_time_step_s = 0.001;
  // Readout is kept in [0, max_readout_time_s]; negative = the median frame interval.
  double max_readout_time_s = -1.0;
  // An estimated readout below this (seconds) sits at its lower bound 0, where a global-shutter
  // camera's is: the bound makes the Gaussian interval wrong (the offset and readout slide together
  // along their ridge by a millisecond at a 1-sigma of 0.2-0.3 ms). The calibration is then also
  // run with the readout held at 0, and the reported intervals widened to hold both answers
  // (offset: the difference added in quadrature; readout: down to 0). 0 = never.
  double readout_boundary_s = 2e-3;

  // Refinement.
  int max_iterations = 60;
  // Cauchy loss scale = robust_scale_factor x the robust (MAD) residual sigma, at least
  // min_robust_scale_px (pixels).
  double robust_scale_factor = 2.5;
  double min_robust_scale_px = 0.15;

  // Input requirements.
  int min_pairs = 20;            // usable pairs needed
  int min_tracks_per_pair = 12;  // a pair with fewer tracks is not used

  // Observability. A rotation-rate axis counts as excited when the gyro's RMS rate about it is at
  // least min_excitation_rate_rad_s; the rotation needs two excited axes, everything needs one.
  double min_excitation_rate_rad_s = 0.02;
  // The rotation between consecutive frames, as the tracks see it (median over pairs of the
  // fitted image rotation angle times the focal length, pixels), must reach this. Below it, track
  // noise (~0.1 px), KLT's bias and the parallax of hand or robot translation (tenths of a pixel)
  // are as large as the signal, and a still recording whose gyro shows vibration passes the rate
  // check yet gives a confident wrong answer (issue 14: 0.019 deg between frames, 0.15 px).
  double min_median_image_rotation_px = 0.5;
  // The reported 1-sigma of each estimated quantity is
  //     sqrt((statistical_sigma_factor * statistical)^2 + systematic^2)
  // (docs/calibration_uncertainty.md). The statistical sigma (CalibrationResult::statistical)
  // counts what varies within the recording, and is still optimistic by about 2x: the errors of
  // nearby tracks are correlated beyond the blocks the cluster-robust covariance uses. The
  // systematic term is what the whole recording shares and no resampling of it can see: KLT's
  // timing bias on rolling-shutter frames (~0.05-0.07 ms), the parallax of the scene's layout, the
  // lens model's misfit. The values below are their size on the simulator benchmark: chosen on one
  // set of 40 bags for >= 90 % coverage per quantity (the rotation: all three axes of >= 90 % of the
  // bags), checked on a second, independent set. Set
  // the factor to 1 and the systematic terms to 0 for the statistical sigma alone.
  double statistical_sigma_factor = 2.5;
  double systematic_time_offset_s = 0.08e-3;
  double systematic_readout_time_s = 0.12e-3;
  double systematic_rotation_rad = 0.2 * 3.14159265358979323846 / 180.0;  // per camera axis
  double systematic_gyro_bias_rad_s = 0.8e-3;                              // per IMU axis
  // Largest statistical 1-sigma (CalibrationResult::statistical) accepted for each estimated
  // quantity: what this recording can determine. The systematic term is the same for every
  // recording, so no recording could lower it and it does not decide a refusal.
  double max_time_offset_sigma_s = 0.00025;
  double max_readout_time_sigma_s = 0.00025;
  double max_rotation_sigma_rad = 0.25 * 3.14159265358979323846 / 180.0;  // per camera axis
  double max_gyro_bias_sigma_rad_s = 0.002;                                // per IMU axis

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// A drifting clock's time offset at camera stamp t: offset_s + rate * (t - reference_s) (seconds;
// rate in s/s). A stamp more than kOtherTimelineS before the reference is on another timeline (time
// went back: a bag loop, a restarted clock), where the line says nothing: the offset at the reference.
constexpr double kOtherTimelineS = 1.0;
inline double timeOffsetOnLine(double offset_s, double rate, double reference_s, double camera_stamp_s) {
  if (rate == 0.0 || camera_stamp_s < reference_s - kOtherTimelineS) return offset_s;
  return offset_s + rate * (camera_stamp_s - reference_s);
}

struct CameraImuCalibration {
  double time_offset_s = 0.0;
  // A drifting clock (the online calibration's line): the offset at camera stamp t is
  // timeOffsetOnLine(time_offset_s, time_offset_rate, time_offset_reference_s, t). Rate 0 (the
  // offline calibration's, and the default) is a constant offset; use timeOffsetAt() wherever a
  // stamp is known.
  double time_offset_rate = 0.0;          // s/s
  double time_offset_reference_s = 0.0;   // camera clock, seconds
  double timeOffsetAt(double camera_stamp_s) const {
    return timeOffsetOnLine(time_offset_s, time_offset_rate, time_offset_reference_s, camera_stamp_s);
  }
  // This calibration with its offset at camera_stamp_s held constant (for code that takes one offset:
  // a pair, a few frames).
  CameraImuCalibration heldAt(double camera_stamp_s) const {
    CameraImuCalibration held = *this;
    held.time_offset_s = timeOffsetAt(camera_stamp_s);
    held.time_offset_rate = 0.0;
    held.time_offset_reference_s = camera_stamp_s;
    return held;
  }
  double readout_time_s = 0.0;
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();               // IMU frame
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();  // R_cam_imu
  // 1-sigma uncertainties (a held quantity: CalibrationOptions::held_*_sigma, 0 by default): the
  // statistical one (CalibrationResult::statistical) inflated, the systematic one and what the
  // held values' 1-sigma move it by added in quadrature (CalibrationOptions::
  // statistical_sigma_factor, held_*_sigma). On the simulator benchmark they cover the actual error of >= 90 %
  // of the estimates, per quantity. The rotation's
  // is about the camera's x, y, z axes (a small rotation exp(e) R_cam_imu with e in the camera
  // frame).
  double time_offset_sigma_s = 0.0;
  double readout_time_sigma_s = 0.0;
  Eigen::Vector3d gyro_bias_sigma_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_sigma_rad = Eigen::Vector3d::Zero();
};

enum class CalibrationStatus {
  kOk,
  kRefused,  // at least one estimated quantity is not observable from this recording
};

struct CalibrationResult {
  CalibrationStatus status = CalibrationStatus::kOk;
  // One sentence per refused quantity: what is missing and what to do about it.
  std::vector<std::string> refusals;
  // Which quantities the refusals name, for a caller that can hold one at a known value.
  struct Refused {
    bool motion = false;  // too little motion for any quantity
    bool time_offset = false;
    bool readout_time = false;
    bool gyro_bias = false;
    bool rotation = false;  // its 1-sigma, rotation about one axis only, or a mount off its permutation
  } refused;
  // Sentences on how the reported intervals were formed beyond the usual (e.g. the readout bound).
  std::vector<std::string> notes;
  // The estimate (filled even when refused, for diagnosis; do not use a refused quantity).
  CameraImuCalibration calibration;

  // The statistical part of calibration's 1-sigma alone (same units): the larger of the
  // residual-based and the block cluster-robust covariance, neither inflated nor with the
  // systematic term. The refusals compare it with the max_*_sigma limits.
  struct Sigmas {
    double time_offset_s = 0.0;
    double readout_time_s = 0.0;
    Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();
    Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();
  } statistical;

  // Diagnostics.
  int pairs_used = 0;
  int tracks_used = 0;
  double coarse_time_offset_s = 0.0;   // best cell of the coarse grid (with the initial readout)
  int coarse_permutation_index = -1;   // into signedAxisPermutations(); -1 when the rotation was held
  int iterations = 0;
  bool converged = false;  // the refinement's steps became negligible before max_iterations
  // The signed axis permutation nearest the estimated mount and how far the mount is from it
  // (deg); index -1 when the rotation was held.
  int nearest_permutation_index = -1;
  double mount_from_permutation_deg = 0.0;
  double initial_median_residual_px = 0.0;  // after the coarse stage
  double median_residual_px = 0.0;          // after refinement (with the lens shift removed for OIS)
  double inlier_fraction = 0.0;             // tracks with a Cauchy weight above 0.5
  Eigen::Vector3d rate_rms_rad_s = Eigen::Vector3d::Zero();  // gyro RMS about its principal axes, descending
  double median_image_rotation_px = 0.0;  // see CalibrationOptions::min_median_image_rotation_px
  double seconds = 0.0;  // wall time of calibrateCameraImu()

  bool ok() const { return status == CalibrationStatus::kOk; }
  // The refusals joined with "; " (empty when ok).
  std::string reason() const;
};

// KLT settings for calibration tracks: the tracker's defaults with an 11 px window instead of
// 21. A window spans rows read out at different times that moved differently, and a wide one
// shifts each track's effective capture time. Measured on a 5 s simulator bag: time offset /
// readout errors +0.17 / -0.27 ms with 21 px, +0.05 / -0.07 ms with 11 px (31 px: +0.32 /
// -0.55 ms), the number of tracks unchanged.
KltOptions calibrationKltOptions();

// Runs the coarse stage, the refinement and the observability checks. Throws
// std::invalid_argument naming the problem for malformed input (bad options, no camera, stamps
// not increasing, a pair naming a frame that does not exist, too few usable pairs).
CalibrationResult calibrateCameraImu(const CalibrationData& data, const CalibrationOptions& options);

// Per-track reprojection errors |x_b - predicted x_b| (pixels, undistorted) of `data` under a
// calibration, no lens-shift elimination; a pair the gyro does not cover gets no entries. For
// reporting how well a calibration aligns the tracks.
std::vector<double> trackResidualsPx(const CalibrationData& data, const CameraImuCalibration& calibration,
                                     RateInterpolation interpolation = RateInterpolation::kLinear);

}  // namespace deep_ois
