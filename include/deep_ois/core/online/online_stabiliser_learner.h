// Online self-calibration of the stabiliser model while the live pipeline runs: the compensated
// frame pairs come in, point tracks between their frames check the compensation in use (a
// residual, a confidence and a fallback to the plain gyro: compensation_check.h) and are turned
// into gyro-anchored lens motions (the same code path as train_stabiliser's images target:
// estimateLensShiftTrajectory + lensMotionsOfTrajectory, over windows of a few seconds), kept in a
// rolling, motion-rich buffer; a background fit on it makes candidates (train_stabiliser's: the
// chain and, from the second fit on, its structural variants and linear-dynamics rows), and the
// candidates (those, the priors given at the start, and always "no lens motion") are scored on the newest
// held-out window (chooseStabiliserModel). The model in use is replaced only by a clearly better
// one; the swap is atomic (a shared_ptr swapped under a mutex, versioned).
//
// A swap is a trial (confirmed_state.h): the per-pair check scores the new model, the one it
// replaced and the plain gyro on the same tracks of the pairs after it; after
// options.confirmation.pairs usable pairs a model worse than the one it replaced is undone, and
// only a confirmed model is written to the file (atomically). No fit runs while a swap is on trial.
// Data already learned from (a replayed recording: windows and pairs whose IMU-clock span was
// already learned from) is not new evidence: it is neither kept for the fits nor counted for a
// confirmation.
//
// Threads: submit() only moves a pair into a bounded queue (it never waits for tracking or a fit;
// a full queue drops the pair, counted). A tracking thread tracks, checks and builds the windows;
// a fit thread fits. Both share one CPU budget (a share of one core, measured on their own thread
// CPU time): a credit accrues at the share and each piece of work is charged what it cost. Work
// starts only when the credit already covers its expected cost, measured on the work before it (a
// fit: the last fits' CPU per lens motion times the lens motions it will use; a window of tracking:
// the last window's), so the average holds over any span, the last fit included; a fit waiting for
// its credit has priority (no new window starts meanwhile). Pairs not tracked for the budget are
// skipped (counted), but only between windows (a window of consecutive pairs is tracked whole: a
// pair skipped inside one would cut it). The destructor stops both (it waits for a fit in progress
// to end).
//
// The linear-dynamics stage is adapted two ways: the solver refits the whole chain with it (the
// candidate table's linear-dynamics rows, from the second fit on, when candidate_kinds asks for
// them: off by default for their CPU), and a recursive least squares
// with forgetting (core/ois/linear_dynamics_rls.h) follows its coefficients with the rest of its
// chain held, fed the training windows at each fit; its model is one more candidate, kept only
// through the choice and the per-pair check's trial (OnlineLearningOptions::linear_dynamics_rls).
//
// A still camera learns nothing and loses nothing: a window whose gyro barely moves is not kept
// (its lens motion says nothing about the stabiliser), and without new data no fit runs. Pure
// C++/Eigen/OpenCV: no ROS.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <opencv2/core.hpp>
#include <string>
#include <thread>
#include <vector>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/linear_dynamics_rls.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"
#include "deep_ois/core/online/atomic_file_write.h"
#include "deep_ois/core/vision/compensation_check.h"
#include "deep_ois/core/online/confirmed_state.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/vision/live_tracking.h"

namespace deep_ois {

struct OnlineFramePair;

struct OnlineLearningOptions {
  bool learning = true;        // false: pairs are still checked (residual, fallback), nothing is fitted
  double window_s = 2.0;       // seconds of consecutive pairs per lens-trajectory estimate
  double buffer_s = 40.0;      // seconds of windows kept; beyond, the least moving one is dropped
  double held_out_s = 6.0;     // the newest windows held out of the fit: the swap is decided there
  double min_training_s = 6.0; // no fit before this many seconds of windows besides the held-out
  double refit_every_s = 4.0;  // seconds of new windows between fits
  // A window whose RMS pan/tilt rate is below this (rad/s) is still: nothing to learn.
  double still_rate_rad_s = 0.03;
  double cpu_share = 0.3;            // of one core, tracking and fitting together, on average
  // The clock the budget accrues on, seconds (empty: wall time). A replay gives its replay time.
  std::function<double()> budget_clock;
  // A window chains consecutive pairs whose time offset (camera -> IMU) moves by at most this rate
  // between them, s/s: a drifting clock followed along a line (the online calibration's
  // apply_drift_rate moves the offset by microseconds a pair). The window's frames are moved onto
  // its first pair's timing by their offset's change, so each frame keeps its own IMU time. A
  // faster change is an applied calibration step: the window being built ends there.
  double max_clock_drift_rate = 1e-3;
  // Pairs waiting for the tracking thread (each holds its two frames until tracked).
  std::size_t max_queued_pairs = 10;
  // The tracker: the live pipeline's (core/vision/feature_tracker.h), within the CPU budget.
  int tracking_width_px = kLiveTrackingWidthPx;  // frames wider than this are tracked on a reduced copy
  CornerDetectorOptions corners = liveTrackingCorners();
  KltOptions klt = liveTrackingKlt();
  StabiliserFitOptions fit = onlineFitOptions();
  // The candidates built from each fit besides the chain (train_stabiliser's, stabiliser_candidates.h).
  // The linear-dynamics rows (kinds.linear_dynamics, off by default) are built from the second
  // fit on, as the structural variants.
  StabiliserCandidateKinds candidate_kinds = onlineCandidateKinds();
  // Recursive least squares with forgetting on the linear-dynamics stage's coefficients
  // (core/ois/linear_dynamics_rls.h), the rest of its chain held. It starts from the model in use or
  // a prior with that stage (else from the first fit's linear-dynamics candidate), is fed at each
  // fit the training windows it has not seen yet (never the held-out ones the choice scores on),
  // and its model is one more candidate of the choice: kept only through the choice and the
  // per-pair check's trial, as every swap. After each fit the best-scored linear-dynamics
  // candidate of the solver (the whole chain refitted) replaces its chain and coefficients, its
  // confidence kept. false: off.
  bool linear_dynamics_rls = true;
  LinearDynamicsRlsOptions rls;
  LensShiftOptions lens;             // patch count and readout come from each pair's timing
  StabiliserChoiceOptions choice;
  CompensationCheckOptions check;
  CompensationFallbackOptions fallback;
  // When a swap is confirmed or undone by the per-pair check (confirmed_state.h).
  ConfirmationOptions confirmation;
  // Where a confirmed model is kept (written atomically: a kill during a fit or a write leaves the
  // last confirmed file); empty = not kept.
  std::string model_path;
  AtomicWriteOptions write;  // its test hook slows the write (~learning_test_write_pause)
  std::string model_file_name = "learned online";  // the file's name field
  CameraDescription camera;                         // recorded in the file
  // Called on the tracking thread with every pair once its tracks are made (before its check),
  // e.g. to feed the online calibration (online_calibration_feed.h). Its CPU time is charged to
  // the budget above, with the tracking's. Must not throw; empty = none.
  std::function<void(const OnlineFramePair&)> on_tracked_pair;

  // The fit's defaults, cheaper than train_stabiliser's (fewer pan-detection thresholds and
  // fewer iterations; the elliptic stroke variant stays): it runs every few seconds in the background.
  static StabiliserFitOptions onlineFitOptions();
  static StabiliserCandidateKinds onlineCandidateKinds();
  std::string validate() const;
};

// One compensated frame pair (camera clock stamps) and what the learner needs of it.
struct OnlineFramePair {
  double stamp_a_s = 0.0, stamp_b_s = 0.0;
  RollingShutterConfig timing;  // patch count, readout, time offset (camera -> IMU clock)
  CameraModel camera;
  std::vector<Eigen::Matrix3d> rotations;          // gyro R_b_a per row patch
  std::vector<Eigen::Matrix3d> gyro_homographies;  // K R K^-1 per patch (the plain gyro)
  std::vector<Eigen::Matrix3d> model_homographies; // the compensation published (empty: none)
  std::vector<CameraRateSample> rates;  // camera-frame gyro up to the pair (overlaps are fine)
  // The frames (8-bit 1/3/4 channels or 16-bit 1 channel), shared, not copied: keep_alive owns
  // their pixels (e.g. the ROS messages) until the tracking thread is done with them.
  cv::Mat image_a, image_b;
  std::shared_ptr<const void> keep_alive;
  // Tracks already made (raw pixels of the camera): used instead of the images when `tracked`.
  std::vector<FeatureMatch> matches;
  bool tracked = false;
  // The check of model_homographies on those tracks, when the caller made it already (the fusion
  // needs it before the next pair): used instead of checking again.
  std::optional<CompensationCheck> check;
};

// The stabiliser model in use.
struct LearnedStabiliser {
  std::uint64_t version = 0;  // 0: the one given at the start; +1 per swap
  std::string name;
  StabiliserModel parameters;
  double held_out_rms_px = 0.0;          // on the held-out window that chose it (NaN: not scored)
  double held_out_rms_without_px = 0.0;  // no lens motion on that window
  std::string reason;                    // the choice's sentence
  // What it was fitted on (recorded in the file when it is confirmed).
  std::size_t training_recordings = 0, training_observations = 0;
};

// The check of one pair, made on the tracking thread.
struct PairVerdict {
  double stamp_a_s = 0.0, stamp_b_s = 0.0;
  CompensationCheck check;
  bool falling_back = false;  // the fallback state after this pair
};

struct OnlineLearningStatus {
  // "off", "collecting", "fitting", "waiting for motion", "over budget" (a fit waits for its credit)
  std::string state;
  std::size_t pairs_submitted = 0, pairs_dropped_busy = 0, pairs_checked = 0, pairs_unusable = 0;
  std::size_t pairs_over_budget = 0;  // skipped by the tracking for the CPU budget
  std::size_t fits_delayed_by_budget = 0;  // fits that waited for their credit before starting
  std::size_t pairs_falling_back = 0;  // checked pairs after which the plain gyro was in use
  std::size_t windows_kept = 0, windows_still = 0, windows_failed = 0, windows_dropped = 0;
  std::size_t pairs_without_tracks = 0;  // left out of the lens motions (too few inlier tracks)
  std::size_t fits = 0, fits_failed = 0, swaps = 0, saves_failed = 0;
  // Swaps taken back: a swap is decided on one held-out window and confirmed on the next (the
  // first held_out_s of windows after it); where the model it replaced is clearly better there,
  // that model is restored (counted in swaps too).
  std::size_t swaps_undone = 0;
  // The per-pair check's verdicts on swaps (confirmed_state.h): confirmed (and written), undone
  // (counted in swaps_undone too), kept in use but not written (worse than the plain gyro).
  std::size_t swaps_confirmed = 0, swaps_undone_by_pairs = 0, swaps_kept_unconfirmed = 0;
  std::size_t saves = 0;  // confirmed models written
  // Data already learned from (a replayed recording): not kept, not counted for a confirmation.
  std::size_t windows_repeated = 0, pairs_repeated = 0;
  std::string confirmation;  // the swap on trial and its pairs so far, or the last verdict
  double buffered_s = 0.0;
  double cpu_s = 0.0;       // thread CPU time spent, seconds (the tracking elsewhere included)
  // Of which (fit thread): the recursive least squares on the linear stage (its evidence: a run of
  // the chain per coefficient column over each window fed), and the fits' linear-dynamics rows.
  double rls_cpu_s = 0.0, linear_rows_cpu_s = 0.0;
  std::size_t rls_windows = 0, rls_lens_motions = 0;  // fed to the recursive least squares
  std::size_t rls_swaps = 0;  // swaps to its model (each a trial of the per-pair check as any swap)
  double tracking_elsewhere_cpu_s = 0.0;  // of which the tracking of pairs handed over tracked
  double wall_s = 0.0;      // since the start
  std::string last_choice;  // the last fit's choice sentence
  std::string last_problem; // the last failure (a window, a fit, a save), empty when none
};

class OnlineStabiliserLearner {
 public:
  // `priors`: the candidates besides a fresh fit (the model found before for this camera, the
  // shipped one); "no lens motion" is added when missing. `initial` is the one in use at the
  // start. Throws std::invalid_argument for bad options, no prior or `initial` out of range.
  OnlineStabiliserLearner(OnlineLearningOptions options, std::vector<ModelCandidate> priors,
                          std::size_t initial);
  ~OnlineStabiliserLearner();
  OnlineStabiliserLearner(const OnlineStabiliserLearner&) = delete;
  OnlineStabiliserLearner& operator=(const OnlineStabiliserLearner&) = delete;

  // Queues the pair; false (counted) when the queue is full. Never waits for tracking or a fit.
  bool submit(OnlineFramePair pair);
  // CPU time (seconds) another thread spent for the learner: the tracking of pairs handed over
  // tracked (the fusion tracks in the compensation callback). Charged to the budget like the
  // learner's own work, so that both together keep to cpu_share on average: the learner's own
  // pairs and fits wait when the tracking takes the share.
  void chargeTrackingElsewhere(double cpu_s);
  // The model in use (a snapshot; a swap replaces it for later calls).
  std::shared_ptr<const LearnedStabiliser> model() const;
  // Whether the plain gyro should be published instead of the model (the checks' hysteresis).
  bool fallingBack() const { return falling_back_.load(); }
  // The checks made since the last call, in pair order.
  std::vector<PairVerdict> takeVerdicts();
  OnlineLearningStatus status() const;
  std::size_t queued() const;  // pairs waiting for the tracking thread
  // Learning on or off (the checks go on); a fit in progress ends first.
  void setLearning(bool on);
  void setCpuShare(double share);
  // Time went back (a bag that loops): the window being built and the queued pairs belong to the
  // other timeline and are dropped; the kept windows stay (the camera is the same).
  void restartTimeline();
  // For tests and benchmarks: waits until the queue is empty and no fit runs (or the timeout). With
  // options.budget_clock given, a fit waiting for credit that the clock has not brought yet counts
  // as idle (the caller moves that clock: nothing happens until it does).
  bool waitIdle(double timeout_s);

 private:
  struct Window;  // lens motions of a few seconds, with their gyro stream
  void trackingLoop();
  void fitLoop();
  void process(OnlineFramePair& pair);
  void closeWindow();
  void fitOnce(std::vector<std::shared_ptr<const Window>> windows);
  // Scores the model in use against the one its swap replaced on the windows after the swap, and
  // restores the replaced one where it is clearly better (chooseStabiliserModel's margins).
  void confirmSwap(const std::shared_ptr<const LearnedStabiliser>& replaced,
                   const std::vector<std::shared_ptr<const Window>>& fresh);
  // Writes a confirmed `model` to options_.model_path (atomic; nothing without a path). Throws on
  // failure (counted by the caller).
  void saveModel(const LearnedStabiliser& model) const;
  // Tracking thread: the per-pair check of the swap on trial (its model, the one it replaced and the
  // plain gyro on the pair's tracks); ends the trial once enough pairs are in.
  void checkTrial(const OnlineFramePair& pair);
  // Tracking thread: whether most of [start_s, end_s] (IMU clock) was already learned from.
  bool alreadyLearnedFrom(double start_s, double end_s) const;
  // Under mutex_ (held by `lock`): blocks until the credit covers the requested fit's expected cost,
  // the request is withdrawn (learning off) or the learner stops; false when stopping.
  bool waitForBudget(std::unique_lock<std::mutex>& lock);
  // Under mutex_: accrues the credit up to now; true when it covers `expected_cpu_s` of tracking
  // and no fit is waiting for the credit.
  bool withinBudget(double expected_cpu_s);
  void accrueCredit();                                // under mutex_
  double expectedFitCpuS(std::size_t lens_motions) const;  // under mutex_
  std::size_t bufferedLensMotions() const;                  // under mutex_: in windows_
  double clockNow() const;
  // Charges `cpu_s` spent, giving back `reserved_s` set aside for it when it started.
  void charge(double cpu_s, double reserved_s = 0.0);

  OnlineLearningOptions options_;
  std::vector<ModelCandidate> priors_;
  std::size_t fits_started_ = 0;  // the fit thread's own count (no lock)
  FeatureTracker tracker_;
  CompensationFallback fallback_;  // tracking thread only
  std::atomic<bool> falling_back_{false};

  mutable std::mutex mutex_;  // everything below unless said
  std::condition_variable wake_tracking_, wake_fit_, idle_;
  bool stopping_ = false;
  std::deque<OnlineFramePair> queue_;
  bool tracking_busy_ = false;
  bool fit_requested_ = false, fitting_ = false;
  // The last swap on probation: the model it replaced, and the end of the newest window it was
  // decided on; confirm_requested_ once held_out_s of windows after it are in, confirming_ while
  // the fit thread scores the two there.
  std::shared_ptr<const LearnedStabiliser> replaced_;
  double probation_after_s_ = 0.0;
  bool confirm_requested_ = false, confirming_ = false;
  std::shared_ptr<const LearnedStabiliser> model_;
  bool on_trial_ = false;  // mirrors trials_->onTrial(): no fit starts meanwhile
  std::vector<PairVerdict> verdicts_;
  std::vector<std::shared_ptr<const Window>> windows_;  // oldest first
  double new_seconds_ = 0.0;  // of windows since the last fit
  OnlineLearningStatus status_;
  double credit_s_ = 0.0;  // CPU seconds the budget allows now, less a running fit's reservation
  double credit_stamp_s_ = 0.0;
  std::deque<double> fit_cpu_per_motion_s_;  // the last fits' measured CPU per lens motion, seconds
  double fit_waiting_cpu_s_ = 0.0;  // the credit a requested fit waits for (0: none waits)
  bool fit_held_ = false;           // the credit was found short for the requested fit...
  double fit_held_at_s_ = 0.0;      // ...at this budget clock time
  double started_s_ = 0.0;

  // Tracking thread only: the window being built. Its frames' stamps on the timing of its first
  // pair (camera stamp + the pair's offset - the first pair's offset: the same IMU time).
  std::vector<double> window_stamps_s_;
  double window_last_stamp_s_ = 0.0;   // the newest frame's own camera stamp (the next pair's frame a)
  double window_last_offset_s_ = 0.0;  // the time offset of the newest pair
  std::vector<LensShiftPairObservation> window_pairs_;
  CameraModel window_camera_;
  RollingShutterConfig window_timing_;
  std::deque<CameraRateSample> rates_;  // recent camera-frame gyro, increasing stamps
  std::uint64_t timeline_ = 0;          // bumped by restartTimeline (under mutex_)
  std::uint64_t window_timeline_ = 0;
  double window_cpu_s_ = 0.0;       // CPU of the window being tracked so far
  double last_window_cpu_s_ = 0.0;  // CPU of the last window (of the last pair outside windows)

  // The confirm-then-persist rule over the model in use. Its own lock (taken before mutex_, never
  // after): a confirmed model is written under it, and model() must not wait for a write.
  mutable std::mutex trials_mutex_;
  std::unique_ptr<ConfirmedState<std::shared_ptr<const LearnedStabiliser>>> trials_;

  // Tracking thread only: the trial's two models run on the pairs' gyro (as the output's
  // compensator does), rebuilt per trial and camera; the IMU-clock spans learned from, merged.
  std::uint64_t shadow_trial_ = ~std::uint64_t{0};
  Eigen::Matrix3d shadow_K_ = Eigen::Matrix3d::Zero();
  std::unique_ptr<StabiliserCompensator> shadow_trial_model_, shadow_replaced_model_;
  std::vector<std::pair<double, double>> learned_spans_s_;

  // Fit thread only: the recursive least squares on the linear stage, the chain its coefficients go
  // in, and the end (IMU clock) of the newest window it was fed or the solver fitted it on.
  std::unique_ptr<LinearDynamicsRls> rls_;
  StabiliserModel rls_chain_;
  double rls_fed_until_s_ = -std::numeric_limits<double>::infinity();
  // Fit thread: feeds the training windows not fed yet; its candidate (none without an RLS).
  std::optional<ModelCandidate> feedRls(const std::vector<std::shared_ptr<const Window>>& training);
  // Fit thread: the solver's best-scored linear-dynamics candidate becomes the RLS's start.
  void rebaseRls(const std::vector<ModelCandidate>& candidates, const StabiliserChoice& choice,
                 std::size_t rls_candidate, double trained_until_s);

  std::thread tracking_thread_, fit_thread_;
};

}  // namespace deep_ois
