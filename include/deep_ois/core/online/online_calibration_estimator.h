// Online camera-IMU calibration while the live pipeline runs: from the point tracks between
// consecutive frames (the ones the online learner's per-pair check already follows) and the gyro
// stream, the time offset, the rolling-shutter readout time, the gyro bias and, when it is not
// known, the mount (a signed axis permutation plus a small rotation) are estimated, each with its
// 1-sigma, tracked through drift and jumps, and a new calibration is offered for use only when it
// is confidently better on pairs it was not fitted on.
//
// How:
//  - Every `refit_every_s` of new pairs, the newest `window_s` of pairs are calibrated by the
//    offline estimator itself (calibrateCameraImu: coarse offset x permutation search, the
//    Levenberg-Marquardt refinement on the per-track reprojection residual, its uncertainty), so
//    there is one residual and one cost for both. The coarse search spans `first_search_s` around
//    the calibration in use until a fit is accepted, then `search_s` around the estimate.
//  - Each window's estimate is a measurement with its reported 1-sigma. A random-walk filter per
//    quantity (readout, bias per axis) fuses them: the variance grows by (drift rate x elapsed)^2
//    between windows, so old windows are forgotten at the pace the quantity may drift.
//  - The offset's model is a line with a drift rate (clock_offset_filter.h): the window's stamps
//    are moved by that line, so the drift is removed inside the window; overlapping windows count
//    once per window length, and the windows' 1-sigma is scaled by what the innovations show, so
//    that the reported 1-sigma is honest. The estimate is the line at the newest pair.
//  - A window further from the line than clock.suspect_sigmas may hold a jump (a camera app
//    restarted): the newest `jump_window_s` of pairs are fitted at once (ahead of the CPU budget:
//    it may owe up to `max_borrow_s`); when they are beyond clock.jump_sigmas, the filter restarts
//    there (keeping the drift rate) and older pairs leave the window.
//  - The mount is searched over the 24 signed axis permutations until two consecutive accepted
//    windows find the same permutation; from then on a window finding another permutation is not
//    used, and the small rotation about the permutation is fused like the other quantities.
//  - Each swap remembers the state before the fit that offered it: when the caller's per-pair
//    check undoes the swap, rewindBeforeSwap() returns the estimator there.
//  - The calibration in use is a line too (apply_drift_rate): its offset, its drift rate and the
//    camera stamp where the offset holds; whoever applies it takes the line at each frame. The
//    rate is applied only when the clock model tells it from zero (applied_rate_sigmas), else the
//    offset is a constant carried along the line.
//  - A candidate (the filtered estimate after a fit) waits for `held_out_s` of pairs after its
//    window and is scored there against the calibration in use: the mean track residual over the
//    tracks that either explains (within `outlier_px`). It replaces the calibration in use only when
//    lower by the stabiliser model swap's margins (StabiliserChoiceOptions: 5 % and 0.005 px).
//  - A window where the camera hardly rotates, or with too few tracked pairs (no texture), changes
//    nothing and says "needs motion".
//
// Not thread-safe: one caller (the learner's background thread, a replay) feeds and updates it.
// Pure Eigen + OpenCV: no ROS.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/online/clock_offset_filter.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

struct OnlineCalibrationOptions {
  double window_s = 3.0;       // seconds of pairs per fit
  double refit_every_s = 1.5;  // seconds of new pairs between fits
  double held_out_s = 1.5;     // seconds of pairs after a fit's window on which its candidate is scored
  int max_tracks_per_pair = 60;  // more tracks per pair are thinned evenly (cost)
  // A window with more pairs is thinned evenly, counted back from the newest pair (cost: a long
  // window then costs what a short one does, and sees more of the motion). 0 = every pair.
  int max_pairs_per_window = 0;
  // CPU budget, share of one core on the stream's clock (the pairs' stamps): a credit accrues at
  // this share and each fit or score is charged its thread CPU time; a fit starts only when the
  // credit covers what the last one cost (else it waits for later pairs: fits_over_budget). The
  // credit saved is capped at 10 s of the share. 0 = no budget.
  double cpu_share = 0.12;
  // The mount is unknown (search the 24 signed axis permutations until it is found) or held at
  // the starting calibration's rotation.
  bool estimate_rotation = true;
  int rotation_every = 4;  // once the mount is found, its rotation is refined on every n-th window
  bool estimate_gyro_bias = true;
  // OIS: the calibration's per-frame lens shift (kPerFrameShift) keeps the lens from absorbing
  // the timing; kNone for a fixed lens or for tracks from which the lens motion was removed.
  LensShiftHandling lens_shift = LensShiftHandling::kNone;
  // Coarse offset search half-width around the estimate: before the first accepted fit, and after.
  double first_search_s = 0.1;
  double search_s = 0.03;
  // The offset's clock model: its random walks, the jump threshold (also the readout's), the
  // learned scale of the windows' 1-sigma.
  ClockModelOptions clock;
  // A suspected jump: the newest this many seconds of pairs are fitted at once and, when they are a
  // jump, the filter restarts from them (0 = the suspect window itself is tested for a jump).
  double jump_window_s = 1.5;
  // CPU seconds the budget may owe for a jump's fit: it runs when the debt is below this, and the
  // next fits wait until the debt is repaid. Beyond the share, at most this plus one fit is spent.
  double max_borrow_s = 1.0;
  // How fast the readout and the bias may drift (their filters' random walk), per second.
  double readout_drift_s_per_s = 2e-5;
  double bias_drift_rad_s_per_s = 2e-4;
  // A window's estimate counts only when its reported 1-sigma is below these (the window
  // determines it at all); the filter then narrows it further.
  double max_offset_sigma_s = 2e-3;
  double max_readout_sigma_s = 3e-3;
  double max_bias_sigma_rad_s = 0.01;
  double max_rotation_sigma_rad = 2.0 * 3.14159265358979323846 / 180.0;
  // The held-out score: tracks off by more than this under both calibrations are outliers.
  double outlier_px = 2.0;
  // The margins of a swap (the stabiliser model choice's: min_relative_improvement,
  // min_improvement_px).
  StabiliserChoiceOptions margins;
  bool refine_when_not_worse = true;
  double refine_sigmas = 2.0;
  // A candidate whose offset differs from the one in use by more than this (seconds) is also a
  // refinement when not worse, however wide the estimate's interval: a drift of 3 ms a minute
  // leaves a 2-sigma interval of ~0.3 ms in about 12 s. 0 = the sigma rule alone.
  double refine_offset_s = 0.15e-3;
  // The calibration in use carries the clock model's drift rate (CameraImuCalibration::
  // time_offset_rate): the offset applied to a frame is the line at its stamp, so a drifting clock
  // is followed between swaps instead of being left behind until the next one. false: a constant
  // offset, carried ahead by the rate when it is applied (half an interval ahead of the drift).
  // The gyro flow then gives every frame another offset (a new calibration epoch a frame); the
  // online stabiliser learner's windows chain across it (OnlineLearningOptions::max_clock_drift_rate).
  bool apply_drift_rate = true;
  // The drift rate is applied only when the clock model tells it from zero: beyond this many of
  // its 1-sigma (ClockOffsetFilter::rateSigma, the windows' shared error included). A rate within
  // it is the windows' shared error as often as a drift: the offset is then applied as a constant,
  // carried along the line as with apply_drift_rate false. 0 = the rate whenever apply_drift_rate.
  double applied_rate_sigmas = 1.0;
  // The offset and the readout slide together along a ridge in a window of a few seconds (a
  // later readout and an earlier offset explain the same tracks; about -0.7 ms of offset per ms
  // of readout on the benchmark cameras), so a window measuring both measures the offset ~2x
  // worse than one with the readout known. Once the readout's filter is within this 1-sigma
  // (seconds), the windows hold the readout at the filtered value and measure the offset alone,
  // except every readout_every-th window, which measures both and keeps the readout tracked.
  // 0 = always estimate the readout in every window.
  double hold_readout_below_sigma_s = 1e-3;
  int readout_every = 4;
  // The per-window calibration (its estimate_* flags, offsets and refusal limits are set per fit;
  // iterations, robust loss and track requirements are taken from here).
  CalibrationOptions calibration = defaultWindowCalibration();

  static CalibrationOptions defaultWindowCalibration();
  std::string validate() const;  // empty when usable, else a sentence naming the bad field
};

// One frame pair's tracks: camera-clock stamps of both frames' first rows, raw pixels a -> b.
struct OnlineCalibrationPair {
  double stamp_a_s = 0.0;
  double stamp_b_s = 0.0;
  std::vector<FeatureMatch> matches;
};

struct OnlineCalibrationStatus {
  // "needs motion" (the last window could not say anything), "converging" (no fit accepted yet),
  // "tracking" (the estimate follows the windows), "jump" (the last window restarted the filter).
  std::string state = "converging";
  CameraImuCalibration estimate;  // the filtered estimate with its 1-sigmas
  CameraImuCalibration in_use;    // the calibration offered for use (the start until a swap)
  std::uint64_t version = 0;      // +1 per swap of in_use
  bool mount_found = false;       // the permutation was confirmed (or held from the start)
  int mount_permutation_index = -1;
  std::size_t pairs = 0, pairs_without_tracks = 0;
  std::size_t fits = 0, fits_needing_motion = 0, fits_rejected = 0, jumps = 0;
  std::size_t fits_over_budget = 0;  // times a due fit waited for its CPU credit
  std::size_t fits_borrowed = 0;     // jump fits run on borrowed credit
  std::size_t rewinds = 0;           // rewindBeforeSwap() calls that found their swap
  double offset_noise_scale = 1.0;   // the clock model's learned scale of the windows' 1-sigma
  double window_correlation = 0.0;   // ... and the learned correlation of consecutive windows
  // The last accepted window's own measurement of the offset: where (camera clock, the window's
  // middle), what, and its reported 1-sigma (seconds); windows_measured counts them.
  double window_stamp_s = 0.0, window_offset_s = 0.0, window_offset_sigma_s = 0.0;
  std::size_t windows_measured = 0;
  double cpu_s = 0.0;                // thread CPU time of fits and scores so far, seconds
  double stream_s = 0.0;             // seconds of pairs seen (the budget's clock)
  std::size_t candidates_scored = 0;
  std::size_t swaps = 0;        // in_use replaced (refinements included)
  std::size_t refinements = 0;  // of which: not clearly better, no worse, and outside the 3-sigma
  double last_fit_seconds = 0.0;  // wall time of the last window's calibration, seconds
  double held_out_in_use_px = 0.0, held_out_candidate_px = 0.0;  // the last comparison
  std::string last_reason;  // one sentence: what the last fit or comparison found
};

class OnlineCalibrationEstimator {
 public:
  // `start`: the calibration in use (time offset added to camera stamps gives IMU time; readout;
  // bias in the IMU frame; R_cam_imu). Throws std::invalid_argument for bad options or camera.
  OnlineCalibrationEstimator(OnlineCalibrationOptions options, CameraModel camera, CameraImuCalibration start);

  // IMU frame, IMU clock, raw (bias not removed). Older or equal stamps than the last are ignored.
  void addGyro(const ImuSample& sample);
  // Pairs in stamp order; a pair older than the last is ignored (use restartTimeline on a loop).
  void addPair(OnlineCalibrationPair pair);
  // Scores a waiting candidate when its held-out pairs are in, and fits the newest window when
  // refit_every_s of new pairs came in since the last fit. True when in_use changed.
  bool update();
  // Whether update() would do work now (a fit or a score is due).
  bool due() const;
  const OnlineCalibrationStatus& status() const { return status_; }
  // Time went back: the buffered pairs and gyro belong to the other timeline and are dropped; the
  // estimate and the calibration in use stay.
  void restartTimeline();
  // The swap that made status().version equal to `version` was undone by the caller (its per-pair
  // check found it worse): the estimator returns to the state it had before the fit that offered
  // it (the filters, the mount, the estimate, the calibration in use then); later swaps are
  // forgotten, the buffered pairs and gyro stay (they are data) and version does not go back (it
  // counts swaps). False, and nothing changes, when that swap is not among the last kRememberedSwaps.
  bool rewindBeforeSwap(std::uint64_t version);
  static constexpr std::size_t kRememberedSwaps = 8;
  // The offset's clock model (its line, rate, learned scale).
  const ClockOffsetFilter& clockModel() const { return clock_; }

  // The held-out score: mean |x_b - predicted| over the tracks of `pairs` that either calibration
  // explains within outlier_px, for both (pixels); NaN when no pair is covered by the gyro. A
  // drifting calibration (time_offset_rate) is taken with its offset at each pair.
  void scorePair(const std::vector<OnlineCalibrationPair>& pairs, const CameraImuCalibration& a,
                 const CameraImuCalibration& b, double* a_px, double* b_px, int* tracks) const;

 private:
  struct Filter {
    bool initialised = false;
    double value = 0.0, variance = 0.0, stamp_s = 0.0;
  };
  // Whether the candidate differs from the calibration in use by more than refine_sigmas.
  bool outsideEstimate(const CameraImuCalibration& in_use, const CameraImuCalibration& estimate) const;
  // With offset_threshold, also when the offsets differ by more than refine_offset_s.
  bool outsideEstimate(const CameraImuCalibration& in_use, const CameraImuCalibration& estimate,
                       bool offset_threshold) const;
  void fit();
  void scoreCandidate();
  // Kalman update of a random-walk filter; with `jumped`, a value further than jump_sigmas combined
  // sigmas sets *jumped and changes nothing (returns false).
  bool fuse(Filter& filter, double value, double sigma, double drift_per_s, double stamp_s, bool* jumped) const;
  // The pairs of [begin_s, end_s] (not before window_floor_s_), each frame's stamp moved by the
  // clock model's offset at it (along_model: the drift removed; `offset_s` before the model
  // starts), else by `offset_s`.
  CalibrationData windowData(double begin_s, double end_s, double offset_s, bool along_model) const;
  // One window's fit and the checks of its result: false when it says nothing (counted, the
  // reason in last_reason); *rejected names an interval too wide.
  bool calibrateWindow(const CalibrationData& data, const CalibrationOptions& options, const std::string& label,
                       CalibrationResult* result, std::string* rejected);
  double shiftAt(double stamp_s, double offset_s) const;
  // What a fit changes, kept to rewind an undone swap.
  struct ModelState {
    ClockOffsetFilter clock;
    Filter readout;
    Filter bias[3];
    Eigen::Matrix3d rotation;
    Eigen::Vector3d rotation_variance;
    int last_permutation = -1;
    bool any_accepted = false, mount_found = false;
    int mount_permutation_index = -1;
    double window_floor_s = -1e300;
    CameraImuCalibration estimate, in_use;
  };
  ModelState modelState() const;
  double gyroEnd() const;
  bool withinBudget() const;

  OnlineCalibrationOptions options_;
  CameraModel camera_;
  std::deque<OnlineCalibrationPair> pairs_;  // oldest first, window_s + held_out_s kept
  std::deque<ImuSample> gyro_;
  double new_pairs_s_ = 0.0;  // of pairs since the last fit
  double last_pair_stamp_s_ = -1e300;
  ClockOffsetFilter clock_;
  double window_floor_s_ = -1e300;  // camera clock: pairs before it are not fitted (before a jump)
  double last_fit_end_s_ = -1e300;  // the last accepted window's end (its overlap with the next)
  Filter readout_;
  Filter bias_[3];
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d rotation_variance_ = Eigen::Vector3d::Zero();  // rad^2 per camera axis, once fused
  int last_permutation_ = -1;  // of the last accepted window while the mount is searched
  bool any_accepted_ = false;
  // The candidate waiting for its held-out pairs (after candidate_after_s_, camera clock).
  bool candidate_waiting_ = false;
  CameraImuCalibration candidate_;
  double candidate_rate_ = 0.0;  // the offset filter's drift rate with it (s/s)
  double candidate_after_s_ = 0.0;
  ModelState candidate_before_;  // before the fit that offered the candidate
  struct Remembered {
    std::uint64_t version = 0;  // the version the swap made
    ModelState before;
  };
  std::deque<Remembered> swaps_;  // the last kRememberedSwaps, oldest first
  OnlineCalibrationStatus status_;
  double credit_s_ = 0.0;          // CPU seconds the budget allows now
  double last_work_cpu_s_ = 0.0;   // what the last fit cost
  bool budget_said_ = false;       // the due fit waiting for credit was counted
  double work_started_cpu_s_ = 0.0;  // thread CPU clock when the current update() began
};

}  // namespace deep_ois
