#include "deep_ois/core/online/online_stabiliser_learner.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/ground_truth/lens_motion_observations.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"

namespace deep_ois {

struct OnlineStabiliserLearner::Window {
  StabiliserFitRecording recording;  // its own gyro stream (warm-up included) and lens motions
  double start_s = 0.0, end_s = 0.0; // IMU clock span of its pairs
  double motion_rad_s = 0.0;         // RMS pan/tilt rate: how much it tells about the stabiliser
  double seconds() const { return end_s - start_s; }
};

namespace {

// Whether the model has a linear-dynamics stage with coefficients (what the RLS adapts).
bool hasLinearDynamics(const StabiliserModel& model) {
  const LinearDynamicsValues* linear = model.find<LinearDynamicsValues>();
  return linear && linear->active();
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// A window shorter than this (pairs stopped chaining early) is too short for its trajectory's
// smoothness prior to hold: dropped.
constexpr double kMinimumWindowFraction = 0.5;
// Credit the budget may save up while idle, in seconds of the share (a burst after a quiet time).
constexpr double kBudgetBurstS = 20.0;
// A fit's expected CPU: the highest CPU per lens motion among the last kFitCostHistory fits, times
// the lens motions it will use (its training and held-out windows: its cost grows with both), times
// a margin. Measured, so it follows whatever a fit costs on this machine with these options. The
// cost per lens motion is not constant: it grew with the data, 0.07-0.41 ms from one fit to the
// next in the replays (up to 1.8x between consecutive fits); the highest of a few and the margin
// keep most fits within their estimate, and the leftover of an overestimate is spent afterwards.
constexpr std::size_t kFitCostHistory = 4;
constexpr double kFitCostMargin = 1.5;
// Before any fit was measured, CPU seconds per lens motion: above the first fits measured at
// 360x270-640x480, 30 and 60 frames/s (0.07-0.17 ms on the development machine).
// Whatever a fit costs beyond its estimate is a debt, paid back before any other work starts.
constexpr double kStartFitCpuPerMotionS = 0.4e-3;
// A window or a pair whose IMU-clock span was learned from for at least this fraction is replayed
// data (the same recording again, a bag that loops): not new evidence. A live stream never
// overlaps itself; a replay of a bag overlaps its first pass all but the stamps' jitter.
constexpr double kRepeatedFraction = 0.5;

double wallNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double threadCpuNow() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace

StabiliserFitOptions OnlineLearningOptions::onlineFitOptions() {
  StabiliserFitOptions fit;
  fit.iterations = 15;
  fit.pan_thresholds_rad_s = {0.0, 0.6};
  // The elliptic stroke variant stays (two short refinements more per fit, ~1 % of a core): without
  // it a module with a circular stroke (hall_noisy_circular) was stuck at 45-58 % of the gap after
  // 60 s, with it at 98-100 % from 20 s on (docs/online_learning.md).
  return fit;
}

StabiliserCandidateKinds OnlineLearningOptions::onlineCandidateKinds() {
  StabiliserCandidateKinds kinds;
  // The refits start from the fitted chain: 6 iterations gave the same learning curves as 15 on the
  // tuning recordings (seed 6101: excursion_soft_stroke 87.6 against 87.7 %, 50-60 s) for about a
  // fifth less of the learning's CPU.
  kinds.structural_iterations = 6;
  // The linear-dynamics rows (the chain refitted with the linear stage: a run of the chain per
  // basis function and round) are off by default: measured, they cost 2.3-2.6 s of CPU per fit on
  // ~2,000 lens motions (about what the rest of the fit costs), so the fit after the first one
  // ends far beyond its estimate (gtest ChargedCpuStaysWithinTheShareFitsIncluded: 0.17 s above
  // the share) and its result comes tens of seconds later (docs/results/online_learning.md). On,
  // they are built from the second fit on and the recursive least squares follows them.
  kinds.linear_dynamics = false;
  return kinds;
}

std::string OnlineLearningOptions::validate() const {
  std::ostringstream why;
  if (!(window_s > 0.1)) why << "window_s must be above 0.1 s (got " << window_s << ")";
  else if (!(held_out_s >= window_s)) why << "held_out_s (" << held_out_s << ") must be at least window_s (" << window_s << ")";
  else if (!(min_training_s >= window_s)) why << "min_training_s (" << min_training_s << ") must be at least window_s";
  else if (!(buffer_s >= held_out_s + min_training_s))
    why << "buffer_s (" << buffer_s << ") must hold held_out_s + min_training_s (" << held_out_s + min_training_s << ")";
  else if (!(refit_every_s > 0.0)) why << "refit_every_s must be positive (got " << refit_every_s << ")";
  else if (!(still_rate_rad_s >= 0.0)) why << "still_rate_rad_s must not be negative";
  else if (!(cpu_share > 0.0 && cpu_share <= 1.0)) why << "cpu_share must be in (0, 1] (got " << cpu_share << ")";
  else if (!(max_clock_drift_rate >= 0.0) || !std::isfinite(max_clock_drift_rate))
    why << "max_clock_drift_rate must be finite and >= 0 (got " << max_clock_drift_rate << ")";
  else if (max_queued_pairs < 1) why << "max_queued_pairs must be at least 1";
  else if (tracking_width_px < 64) why << "tracking_width_px must be at least 64 (got " << tracking_width_px << ")";
  if (!why.str().empty()) return why.str();
  if (const std::string problem = rls.validate(); !problem.empty()) return "rls: " + problem;
  for (const std::string& problem : {fit.validate(), lens.validate(), check.validate(), confirmation.validate()})
    if (!problem.empty()) return problem;
  return {};
}

OnlineStabiliserLearner::OnlineStabiliserLearner(OnlineLearningOptions options,
                                                 std::vector<ModelCandidate> priors, std::size_t initial)
    : options_(std::move(options)), priors_(std::move(priors)), fallback_(options_.fallback) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("online stabiliser learning: " + problem);
  tracker_ = FeatureTracker(options_.corners, options_.klt);
  if (priors_.empty() || initial >= priors_.size())
    throw std::invalid_argument("online stabiliser learning: the model in use (" + std::to_string(initial) +
                                ") must be one of the " + std::to_string(priors_.size()) + " priors");
  for (const auto& prior : priors_) {
    const std::string bad = prior.parameters.validate();
    if (!bad.empty()) throw std::invalid_argument("online stabiliser learning: prior " + prior.name + ": " + bad);
  }
  auto model = std::make_shared<LearnedStabiliser>();
  model->name = priors_[initial].name;
  model->parameters = priors_[initial].parameters;
  model->held_out_rms_px = model->held_out_rms_without_px = kNaN;
  model->reason = "in use at the start";
  model_ = model;
  // The model in use at the start is what the file holds (or the ~model file): confirmed already.
  trials_ = std::make_unique<ConfirmedState<std::shared_ptr<const LearnedStabiliser>>>(
      model_, [this](const std::shared_ptr<const LearnedStabiliser>& confirmed) { saveModel(*confirmed); },
      options_.confirmation);
  status_.confirmation = "no swap on trial";
  bool has_still = false;
  for (const auto& prior : priors_) has_still = has_still || isNoLensMotion(prior.parameters);
  if (!has_still) priors_.push_back({"no lens motion", noLensMotion()});
  // The recursive least squares starts from the model in use when it has the linear stage, else
  // from the first prior that has it (else from the first fit's linear-dynamics candidate).
  if (options_.linear_dynamics_rls) {
    std::vector<const StabiliserModel*> starts = {&priors_[initial].parameters};
    for (const auto& prior : priors_) starts.push_back(&prior.parameters);
    for (const StabiliserModel* start : starts) {
      if (!hasLinearDynamics(*start)) continue;
      rls_chain_ = *start;
      rls_ = std::make_unique<LinearDynamicsRls>(start->get<LinearDynamicsValues>().coefficients, options_.rls);
      break;
    }
  }
  status_.state = options_.learning ? "collecting" : "off";
  started_s_ = wallNow();
  credit_stamp_s_ = clockNow();
  tracking_thread_ = std::thread([this] { trackingLoop(); });
  fit_thread_ = std::thread([this] { fitLoop(); });
}

OnlineStabiliserLearner::~OnlineStabiliserLearner() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_tracking_.notify_all();
  wake_fit_.notify_all();
  idle_.notify_all();
  tracking_thread_.join();
  fit_thread_.join();
}

bool OnlineStabiliserLearner::submit(OnlineFramePair pair) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.pairs_submitted;
    if (queue_.size() >= options_.max_queued_pairs) {
      ++status_.pairs_dropped_busy;
      return false;
    }
    queue_.push_back(std::move(pair));
  }
  wake_tracking_.notify_one();
  return true;
}

std::shared_ptr<const LearnedStabiliser> OnlineStabiliserLearner::model() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return model_;
}

std::vector<PairVerdict> OnlineStabiliserLearner::takeVerdicts() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<PairVerdict> out;
  out.swap(verdicts_);
  return out;
}

std::size_t OnlineStabiliserLearner::queued() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.size();
}

OnlineLearningStatus OnlineStabiliserLearner::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  OnlineLearningStatus status = status_;
  status.wall_s = wallNow() - started_s_;
  double buffered = 0.0;
  for (const auto& w : windows_) buffered += w->seconds();
  status.buffered_s = buffered;
  return status;
}

void OnlineStabiliserLearner::setLearning(bool on) {
  std::lock_guard<std::mutex> lock(mutex_);
  options_.learning = on;
  if (!on) {
    fit_requested_ = false;
    fit_waiting_cpu_s_ = 0.0;  // the tracking need not yield to a fit that will not run
    fit_held_ = false;
  }
  status_.state = on ? "collecting" : "off";
}

void OnlineStabiliserLearner::setCpuShare(double share) {
  if (!(share > 0.0 && share <= 1.0))
    throw std::invalid_argument("online stabiliser learning: cpu_share must be in (0, 1] (got " +
                                std::to_string(share) + ")");
  std::lock_guard<std::mutex> lock(mutex_);
  options_.cpu_share = share;
}

void OnlineStabiliserLearner::restartTimeline() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++timeline_;
  queue_.clear();
  // A swap on probation cannot be confirmed on windows of another timeline: it stays.
  replaced_.reset();
  confirm_requested_ = false;
}

bool OnlineStabiliserLearner::waitIdle(double timeout_s) {
  std::unique_lock<std::mutex> lock(mutex_);
  return idle_.wait_for(lock, std::chrono::duration<double>(timeout_s), [this] {
    // A fit held for credit on the caller's clock waits for the caller (the wall clock moves alone).
    const bool fit_waits_for_caller =
        fit_requested_ && fit_held_ && options_.budget_clock && clockNow() == fit_held_at_s_;
    return stopping_ || (queue_.empty() && !tracking_busy_ && !fitting_ && !confirm_requested_ && !confirming_ &&
                         (!fit_requested_ || fit_waits_for_caller || on_trial_));
  });
}

void OnlineStabiliserLearner::charge(double cpu_s, double reserved_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  credit_s_ += reserved_s - cpu_s;
  status_.cpu_s += cpu_s;
}

void OnlineStabiliserLearner::chargeTrackingElsewhere(double cpu_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  credit_s_ -= cpu_s;
  status_.cpu_s += cpu_s;
  status_.tracking_elsewhere_cpu_s += cpu_s;
}

double OnlineStabiliserLearner::clockNow() const {
  return options_.budget_clock ? options_.budget_clock() : wallNow();
}

void OnlineStabiliserLearner::accrueCredit() {
  const double now = clockNow();
  // The saving is capped (a quiet time buys a bounded burst), but never below what a waiting fit
  // needs: a fit dearer than the cap would otherwise never start.
  const double cap = std::max(options_.cpu_share * kBudgetBurstS, fit_waiting_cpu_s_);
  credit_s_ = std::min(credit_s_ + options_.cpu_share * std::max(0.0, now - credit_stamp_s_), cap);
  credit_stamp_s_ = now;
}

bool OnlineStabiliserLearner::withinBudget(double expected_cpu_s) {
  accrueCredit();
  // A waiting fit goes first: tracking that took the credit as it came would starve it.
  return fit_waiting_cpu_s_ == 0.0 && credit_s_ >= expected_cpu_s;
}

std::size_t OnlineStabiliserLearner::bufferedLensMotions() const {
  std::size_t motions = 0;
  for (const auto& w : windows_) motions += w->recording.observations.size();
  return motions;
}

double OnlineStabiliserLearner::expectedFitCpuS(std::size_t lens_motions) const {
  const double per_motion_s =
      fit_cpu_per_motion_s_.empty()
          ? kStartFitCpuPerMotionS
          : kFitCostMargin * *std::max_element(fit_cpu_per_motion_s_.begin(), fit_cpu_per_motion_s_.end());
  return per_motion_s * static_cast<double>(lens_motions);
}

bool OnlineStabiliserLearner::waitForBudget(std::unique_lock<std::mutex>& lock) {
  bool delayed = false;
  for (;;) {
    if (stopping_) return false;
    if (!fit_requested_) break;  // learning switched off meanwhile
    fit_waiting_cpu_s_ = expectedFitCpuS(bufferedLensMotions());
    accrueCredit();
    if (credit_s_ >= fit_waiting_cpu_s_) break;
    if (!delayed) ++status_.fits_delayed_by_budget;
    delayed = true;
    fit_held_ = true;
    fit_held_at_s_ = credit_stamp_s_;
    status_.state = "over budget";
    idle_.notify_all();
    // Sleeps until the share should have brought the credit (woken early by a skipped pair or to
    // stop); at most 0.1 s, as the budget clock need not run at the wall clock's pace (a replay).
    const double wait_s = std::clamp((fit_waiting_cpu_s_ - credit_s_) / options_.cpu_share, 0.005, 0.1);
    wake_fit_.wait_for(lock, std::chrono::duration<double>(wait_s));
  }
  fit_waiting_cpu_s_ = 0.0;
  fit_held_ = false;
  return true;
}

void OnlineStabiliserLearner::trackingLoop() {
  for (;;) {
    OnlineFramePair pair;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      tracking_busy_ = false;
      idle_.notify_all();
      wake_tracking_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      tracking_busy_ = true;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) continue;  // dropped by restartTimeline
      pair = std::move(queue_.front());
      queue_.pop_front();
      // A new window (or a pair outside windows) starts only when the credit covers what the last
      // one cost; skipped pairs are counted. A window being built is finished.
      if (window_stamps_s_.empty() && !withinBudget(last_window_cpu_s_)) {
        ++status_.pairs_over_budget;
        if (fit_waiting_cpu_s_ > 0.0) wake_fit_.notify_all();  // the budget clock moved: it may start
        continue;
      }
    }
    const double cpu_start = threadCpuNow();
    try {
      process(pair);
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      status_.last_problem = std::string("pair ") + std::to_string(pair.stamp_b_s) + ": " + e.what();
    }
    pair = OnlineFramePair();  // the frames go back to their owner now
    const double cpu_s = threadCpuNow() - cpu_start;
    charge(cpu_s);
    window_cpu_s_ += cpu_s;
    if (window_stamps_s_.empty()) {  // the window ended (or the pair was not part of one)
      last_window_cpu_s_ = window_cpu_s_;
      window_cpu_s_ = 0.0;
    }
  }
}

void OnlineStabiliserLearner::process(OnlineFramePair& pair) {
  // ---- Tracks on a reduced copy, scaled back to the camera's pixels. ----
  if (!pair.tracked) {
    pair.matches = tracker_.matchAtWidth(pair.image_a, pair.image_b, options_.tracking_width_px);
    pair.tracked = true;
  }
  if (options_.on_tracked_pair) options_.on_tracked_pair(pair);

  // ---- The check of the compensation published for this pair. ----
  if (!pair.model_homographies.empty()) {
    const CompensationCheck check =
        pair.check ? *pair.check
                   : checkCompensation(pair.camera, pair.matches, pair.model_homographies, pair.gyro_homographies,
                                       options_.check);
    const bool back = fallback_.update(check);
    falling_back_.store(back);
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.pairs_checked;
    if (!check.usable) ++status_.pairs_unusable;
    if (back) ++status_.pairs_falling_back;
    verdicts_.push_back({pair.stamp_a_s, pair.stamp_b_s, check, back});
    if (verdicts_.size() > 1000) verdicts_.erase(verdicts_.begin(), verdicts_.begin() + 500);  // nobody reads them
  }

  // ---- The swap on trial, if any: its model against the one it replaced, on this pair. ----
  checkTrial(pair);

  // ---- The gyro stream, kept for the windows' warm-up. ----
  for (const CameraRateSample& r : pair.rates)
    if (rates_.empty() || r.stamp_s > rates_.back().stamp_s) rates_.push_back(r);
  const double keep_s = options_.window_s + options_.fit.warm_up_s + 1.0;
  while (!rates_.empty() && rates_.back().stamp_s - rates_.front().stamp_s > keep_s) rates_.pop_front();

  bool learning = false;
  std::uint64_t timeline = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    learning = options_.learning;
    timeline = timeline_;
  }
  // ---- The window: consecutive pairs of one camera, one timeline and one clock. ----
  // The offset may move along a drifting clock's line (microseconds a pair), not by a step.
  const double offset_step_s = std::abs(pair.timing.time_offset_s - window_last_offset_s_);
  const bool chains = !window_stamps_s_.empty() && window_timeline_ == timeline &&
                      pair.stamp_a_s == window_last_stamp_s_ && window_camera_.K().isApprox(pair.camera.K()) &&
                      window_camera_.width() == pair.camera.width() &&
                      window_timing_.patch_count == pair.timing.patch_count &&
                      window_timing_.readout_time_s == pair.timing.readout_time_s &&
                      offset_step_s <= options_.max_clock_drift_rate * (pair.stamp_b_s - pair.stamp_a_s);
  if (!chains) {
    if (window_timeline_ == timeline) closeWindow();
    window_stamps_s_.clear();
    window_pairs_.clear();
    if (window_timeline_ != timeline) {
      rates_.clear();  // the other timeline's gyro must not warm this one's windows up
      for (const CameraRateSample& r : pair.rates)
        if (rates_.empty() || r.stamp_s > rates_.back().stamp_s) rates_.push_back(r);
    }
    window_timeline_ = timeline;
    if (!learning) return;
    window_stamps_s_.push_back(pair.stamp_a_s);
    window_camera_ = pair.camera;
    window_timing_ = pair.timing;
  }
  if (!learning) {
    window_stamps_s_.clear();
    window_pairs_.clear();
    return;
  }
  LensShiftPairObservation observation;
  observation.frame_a = static_cast<int>(window_stamps_s_.size()) - 1;
  observation.frame_b = observation.frame_a + 1;
  observation.rotations = pair.rotations;
  observation.matches = std::move(pair.matches);
  // Frame b on the window's timing: the IMU time this pair's rotations were integrated at.
  window_stamps_s_.push_back(pair.stamp_b_s + pair.timing.time_offset_s - window_timing_.time_offset_s);
  window_last_stamp_s_ = pair.stamp_b_s;
  window_last_offset_s_ = pair.timing.time_offset_s;
  window_pairs_.push_back(std::move(observation));
  if (window_stamps_s_.back() - window_stamps_s_.front() >= options_.window_s) closeWindow();
}

void OnlineStabiliserLearner::closeWindow() {
  const std::vector<double> stamps = std::move(window_stamps_s_);
  const std::vector<LensShiftPairObservation> pairs = std::move(window_pairs_);
  window_stamps_s_.clear();
  window_pairs_.clear();
  if (pairs.empty() || stamps.back() - stamps.front() < kMinimumWindowFraction * options_.window_s) return;
  const RollingShutterConfig& timing = window_timing_;
  auto window = std::make_shared<Window>();
  window->start_s = patchImuTime(timing, stamps.front(), 0);
  window->end_s = patchImuTime(timing, stamps.back(), timing.patch_count - 1);
  // How much the camera turned: the pan/tilt rate (the stabiliser's input) over the window.
  double sum = 0.0;
  std::size_t count = 0;
  for (const CameraRateSample& r : rates_) {
    if (r.stamp_s < window->start_s || r.stamp_s > window->end_s) continue;
    sum += r.rate_rad_s.head<2>().squaredNorm();
    ++count;
  }
  window->motion_rad_s = count ? std::sqrt(sum / count) : 0.0;
  if (alreadyLearnedFrom(window->start_s, window->end_s)) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.windows_repeated;
    return;
  }
  if (count == 0 || window->motion_rad_s < options_.still_rate_rad_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.windows_still;
    if (options_.learning && !fitting_ && !fit_held_) status_.state = "waiting for motion";
    return;
  }
  try {
    LensShiftOptions lens = options_.lens;
    lens.patch_count = timing.patch_count;
    lens.readout_time_s = timing.readout_time_s;
    const LensShiftTrajectory trajectory = estimateLensShiftTrajectory(window_camera_, stamps, pairs, lens);
    TrajectoryLensMotions motions = lensMotionsOfTrajectory(pairs, trajectory, stamps, timing);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      status_.pairs_without_tracks += motions.pairs_without_tracks;
    }
    if (motions.observations.empty()) throw std::runtime_error("no pair with enough inlier tracks");
    window->recording.name = "online window at " + std::to_string(window->start_s) + " s";
    window->recording.focal_px = window_camera_.K()(0, 0);
    window->recording.observations = std::move(motions.observations);
    // The gyro from warm_up_s before the first lens motion: the fit starts the model there.
    const double from = window->start_s - options_.fit.warm_up_s - 0.01;
    for (const CameraRateSample& r : rates_)
      if (r.stamp_s >= from) window->recording.rates.push_back(r);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.windows_failed;
    status_.last_problem = std::string("window: ") + e.what();
    return;
  }
  // Learned from from now on (merged with the spans it touches).
  std::pair<double, double> span(window->start_s, window->end_s);
  std::vector<std::pair<double, double>> merged;
  for (const auto& s : learned_spans_s_) {
    if (s.second < span.first || s.first > span.second) {
      merged.push_back(s);
    } else {
      span.first = std::min(span.first, s.first);
      span.second = std::max(span.second, s.second);
    }
  }
  merged.push_back(span);
  learned_spans_s_ = std::move(merged);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    windows_.push_back(window);
    ++status_.windows_kept;
    new_seconds_ += window->seconds();
    if (!fitting_ && !fit_held_) status_.state = "collecting";
    // Bounded: beyond buffer_s, the least moving window outside the held-out end goes.
    double total = 0.0;
    for (const auto& w : windows_) total += w->seconds();
    while (total > options_.buffer_s && windows_.size() > 1) {
      double held = 0.0;
      std::size_t first_held = windows_.size();
      while (first_held > 0 && held < options_.held_out_s) held += windows_[--first_held]->seconds();
      std::size_t weakest = 0;
      for (std::size_t k = 1; k < first_held; ++k)
        if (windows_[k]->motion_rad_s < windows_[weakest]->motion_rad_s) weakest = k;
      if (first_held == 0) weakest = 0;
      total -= windows_[weakest]->seconds();
      windows_.erase(windows_.begin() + static_cast<long>(weakest));
      ++status_.windows_dropped;
    }
    if (replaced_ && !confirm_requested_) {
      double fresh = 0.0;
      for (const auto& w : windows_)
        if (w->start_s >= probation_after_s_) fresh += w->seconds();
      if (fresh >= options_.held_out_s) {
        confirm_requested_ = true;
        wake_fit_.notify_all();
      }
    }
    // No fit while a swap is on trial: its verdict comes first (the seconds keep counting).
    if (new_seconds_ >= options_.refit_every_s && total >= options_.held_out_s + options_.min_training_s &&
        options_.learning && !on_trial_) {
      fit_requested_ = true;
      wake_fit_.notify_all();
    }
  }
}

void OnlineStabiliserLearner::fitLoop() {
  for (;;) {
    std::vector<std::shared_ptr<const Window>> windows;
    std::size_t motions = 0;
    double reserved_s = 0.0;
    std::shared_ptr<const LearnedStabiliser> replaced;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      idle_.notify_all();
      wake_fit_.wait(lock, [this] { return stopping_ || fit_requested_ || confirm_requested_; });
      if (stopping_) return;
      if (confirm_requested_) {
        // A confirmation goes before a fit: it scores two models on a few seconds (no fit), and a
        // swap that did worse should not wait for the fit's credit to be taken back.
        confirm_requested_ = false;
        confirming_ = true;
        replaced = std::move(replaced_);  // leaves replaced_ empty: the probation ends here
        for (const auto& w : windows_)
          if (w->start_s >= probation_after_s_) windows.push_back(w);
      }
    }
    if (replaced) {
      const double cpu_start = threadCpuNow();
      confirmSwap(replaced, windows);
      charge(threadCpuNow() - cpu_start);
      std::lock_guard<std::mutex> lock(mutex_);
      confirming_ = false;
      continue;
    }
    {
      std::unique_lock<std::mutex> lock(mutex_);
      if (!waitForBudget(lock)) return;
      if (!fit_requested_) continue;  // learning switched off meanwhile
      fit_requested_ = false;
      fitting_ = true;
      new_seconds_ = 0.0;
      status_.state = "fitting";
      windows = windows_;
      motions = bufferedLensMotions();
      // The expected cost is taken from the credit now, so that the tracking meanwhile spends only
      // what is left; the difference to the measured cost is settled when the fit ends.
      reserved_s = expectedFitCpuS(motions);
      credit_s_ -= reserved_s;
    }
    const double cpu_start = threadCpuNow();
    fitOnce(std::move(windows));
    const double cpu_s = threadCpuNow() - cpu_start;
    charge(cpu_s, reserved_s);
    std::lock_guard<std::mutex> lock(mutex_);
    if (motions > 0) {
      fit_cpu_per_motion_s_.push_back(cpu_s / static_cast<double>(motions));
      if (fit_cpu_per_motion_s_.size() > kFitCostHistory) fit_cpu_per_motion_s_.pop_front();
    }
    fitting_ = false;
    if (status_.state == "fitting") status_.state = options_.learning ? "collecting" : "off";
  }
}

std::optional<ModelCandidate> OnlineStabiliserLearner::feedRls(
    const std::vector<std::shared_ptr<const Window>>& training) {
  if (!rls_) return std::nullopt;
  const double cpu_start = threadCpuNow();
  std::size_t windows = 0, motions = 0;
  for (const auto& window : training) {  // oldest first
    // Consecutive windows share their boundary frame: a window is new when it ends later.
    if (window->end_s <= rls_fed_until_s_) continue;
    StabiliserModel linearised = rls_chain_;
    linearised.get<LinearDynamicsValues>().coefficients = rls_->coefficients();
    try {
      const LinearDynamicsEvidence evidence = linearDynamicsEvidence(linearised, {window->recording}, options_.fit);
      rls_->add(evidence);
      ++windows;
      motions += static_cast<std::size_t>(evidence.rows());
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      status_.last_problem = std::string("linear dynamics RLS: ") + e.what();
    }
    rls_fed_until_s_ = std::max(rls_fed_until_s_, window->end_s);
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status_.rls_cpu_s += threadCpuNow() - cpu_start;
    status_.rls_windows += windows;
    status_.rls_lens_motions += motions;
  }
  if (rls_->samples() == 0) return std::nullopt;
  StabiliserModel model = rls_chain_;
  model.get<LinearDynamicsValues>().coefficients = rls_->coefficients();
  return ModelCandidate{"linear dynamics by recursive least squares on " + std::to_string(rls_->samples()) +
                            " lens motions",
                        std::move(model)};
}

void OnlineStabiliserLearner::rebaseRls(const std::vector<ModelCandidate>& candidates,
                                        const StabiliserChoice& choice, std::size_t rls_candidate,
                                        double trained_until_s) {
  if (!options_.linear_dynamics_rls) return;
  std::size_t best = candidates.size();
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    if (!hasLinearDynamics(candidates[k].parameters) || !std::isfinite(choice.scores[k].rms_px)) continue;
    if (best == candidates.size() || choice.scores[k].rms_px < choice.scores[best].rms_px) best = k;
  }
  if (best == candidates.size() || best == rls_candidate) return;  // none, or its own is the best
  const StabiliserModel& chain = candidates[best].parameters;
  const LinearDynamicsValues& linear = chain.get<LinearDynamicsValues>();
  const bool same_basis = rls_ && rls_->coefficients().cols() == linear.coefficients.cols() &&
                          rls_chain_.get<LinearDynamicsValues>().sameForm(linear);
  if (same_basis)
    rls_->rebase(linear.coefficients);  // the confidence in this basis' coefficients kept
  else
    rls_ = std::make_unique<LinearDynamicsRls>(linear.coefficients, options_.rls);
  rls_chain_ = chain;
  // What the solver fitted it on is not fed again.
  rls_fed_until_s_ = std::max(rls_fed_until_s_, trained_until_s);
}

void OnlineStabiliserLearner::fitOnce(std::vector<std::shared_ptr<const Window>> windows) {
  // The newest windows are held out: the swap is decided on data no candidate was fitted to.
  std::vector<StabiliserFitRecording> training, held_out;
  std::vector<std::shared_ptr<const Window>> training_windows;  // oldest first
  double held = 0.0;
  for (std::size_t k = windows.size(); k-- > 0;) {
    if (held < options_.held_out_s) {
      held += windows[k]->seconds();
      held_out.push_back(windows[k]->recording);
    } else {
      training.push_back(windows[k]->recording);
      training_windows.insert(training_windows.begin(), windows[k]);
    }
  }
  double trained_until_s = -std::numeric_limits<double>::infinity();
  for (const auto& w : training_windows) trained_until_s = std::max(trained_until_s, w->end_s);
  const std::shared_ptr<const LearnedStabiliser> current = model();
  std::vector<ModelCandidate> candidates = {{current->name + " (in use)", current->parameters}};
  // The recursive least squares first: fed the training windows it has not seen, with the chain the
  // solver gave it last time (the solver's new candidates come after).
  std::size_t rls_candidate = std::numeric_limits<std::size_t>::max();
  if (std::optional<ModelCandidate> tracked = feedRls(training_windows)) {
    rls_candidate = candidates.size();
    candidates.push_back(std::move(*tracked));
  }
  try {
    const StabiliserFitResult fit = fitStabiliser(training, options_.fit);
    const std::string on = "fit on " + std::to_string(fit.observations_used) + " lens motions: ";
    // The first fit leaves out the structural variants and the linear-dynamics rows (their refits
    // cost a few times the fit): a camera far from its starting model gets a close model seconds
    // earlier; the others come from the next fit on.
    StabiliserCandidateKinds kinds = options_.candidate_kinds;
    const bool first = fits_started_++ == 0;
    if (first) kinds.structural = false;
    const bool linear_rows = kinds.linear_dynamics && !first;
    kinds.linear_dynamics = false;
    for (ModelCandidate& built : stabiliserCandidates(fit, training, options_.fit, kinds))
      candidates.push_back({on + built.name, std::move(built.parameters)});
    if (linear_rows) {
      // Built apart to measure their CPU: the rows with the linear stage alone.
      const double cpu_start = threadCpuNow();
      StabiliserCandidateKinds linear_only;
      linear_only.structural = false;
      linear_only.structural_iterations = kinds.structural_iterations;
      for (ModelCandidate& built : stabiliserCandidates(fit, training, options_.fit, linear_only))
        if (hasLinearDynamics(built.parameters)) candidates.push_back({on + built.name, std::move(built.parameters)});
      std::lock_guard<std::mutex> lock(mutex_);
      status_.linear_rows_cpu_s += threadCpuNow() - cpu_start;
    }
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.fits_failed;
    status_.last_problem = std::string("fit: ") + e.what();
  }
  for (const auto& prior : priors_) candidates.push_back(prior);
  const StabiliserChoice choice = chooseStabiliserModel(candidates, 0, held_out, options_.choice);
  rebaseRls(candidates, choice, rls_candidate, trained_until_s);
  std::shared_ptr<LearnedStabiliser> replacement;
  if (choice.replaced_incumbent) {
    replacement = std::make_shared<LearnedStabiliser>();
    replacement->version = current->version + 1;
    replacement->name = candidates[choice.chosen].name;
    replacement->parameters = candidates[choice.chosen].parameters;
    replacement->held_out_rms_px = choice.scores[choice.chosen].rms_px;
    replacement->held_out_rms_without_px = choice.scores[choice.chosen].rms_without_model_px;
    replacement->reason = choice.reason;
    replacement->training_recordings = training.size();
    for (const auto& r : training) replacement->training_observations += r.observations.size();
  }
  // A swap is a trial: in use at once, written only once the per-pair check confirms it.
  std::unique_lock<std::mutex> trials_lock(trials_mutex_, std::defer_lock);
  if (replacement) {
    trials_lock.lock();
    trials_->startTrial(replacement);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++status_.fits;
  status_.last_choice = choice.reason;
  if (replacement) {
    // On probation: confirmed or undone on the first held_out_s of windows after the ones it was
    // decided on (confirmSwap).
    replaced_ = current;
    probation_after_s_ = windows.empty() ? 0.0 : windows.back()->end_s;
    confirm_requested_ = false;
    model_ = replacement;
    ++status_.swaps;
    if (choice.chosen == rls_candidate) ++status_.rls_swaps;
    on_trial_ = true;
    fit_requested_ = false;
    status_.confirmation = "on trial: " + replacement->name + ", 0 of " +
                           std::to_string(options_.confirmation.pairs) + " pairs checked";
  }
}

void OnlineStabiliserLearner::saveModel(const LearnedStabiliser& model) const {
  if (options_.model_path.empty()) return;
  StabiliserModelFile file;
  file.name = options_.model_file_name + ": " + model.name;
  file.parameters = model.parameters;
  file.camera = options_.camera;
  file.training.target = "gyro-anchored lens shift (images), learned online, confirmed by the per-pair check";
  file.training.recordings = model.training_recordings;
  file.training.observations = model.training_observations;
  file.training.rms_px = kNaN;
  file.training.rms_without_model_px = kNaN;
  file.training.held_out_rms_px = model.held_out_rms_px;
  file.training.held_out_rms_without_model_px = model.held_out_rms_without_px;
  // The same text as StabiliserModelFile::save, written beside the file and renamed over it.
  writeFileAtomically(options_.model_path,
                      "# deep_ois learned stabiliser model (core/ois/stabiliser_model.h): " + file.name + "\n" +
                          file.toYaml(),
                      options_.write);
}

bool OnlineStabiliserLearner::alreadyLearnedFrom(double start_s, double end_s) const {
  if (!(end_s > start_s)) return false;
  double overlap_s = 0.0;
  for (const auto& span : learned_spans_s_)
    overlap_s += std::max(0.0, std::min(end_s, span.second) - std::max(start_s, span.first));
  return overlap_s >= kRepeatedFraction * (end_s - start_s);
}

void OnlineStabiliserLearner::checkTrial(const OnlineFramePair& pair) {
  const RollingShutterConfig& timing = pair.timing;
  if (pair.rotations.empty() || pair.gyro_homographies.size() != pair.rotations.size()) return;
  std::vector<double> times_a, times_b;
  for (int i = 0; i < timing.patch_count; ++i) {
    times_a.push_back(patchImuTime(timing, pair.stamp_a_s, i));
    times_b.push_back(patchImuTime(timing, pair.stamp_b_s, i));
  }
  if (times_a.size() != pair.rotations.size()) return;
  if (alreadyLearnedFrom(times_a.front(), times_b.back())) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++status_.pairs_repeated;  // its verdict would be on data the trial was chosen with
    return;
  }
  std::lock_guard<std::mutex> trials_lock(trials_mutex_);
  if (!trials_->onTrial()) return;
  const Eigen::Matrix3d& K = pair.camera.K();
  if (shadow_trial_ != trials_->trialId() || !shadow_K_.isApprox(K)) {
    // Both start from a centred lens warmed up on the pair's gyro history, as the output's
    // compensator does after a swap.
    shadow_trial_model_ = std::make_unique<StabiliserCompensator>(trials_->inUse()->parameters, K);
    shadow_replaced_model_ = std::make_unique<StabiliserCompensator>(trials_->replaced()->parameters, K);
    shadow_trial_ = trials_->trialId();
    shadow_K_ = K;
  }
  std::vector<std::vector<Eigen::Matrix3d>> compensations;
  for (StabiliserCompensator* shadow : {shadow_trial_model_.get(), shadow_replaced_model_.get()}) {
    shadow->followTimeline(times_a.front(), times_b.front());
    shadow->addRates(pair.rates);
    const StabiliserCompensation c = shadow->compensate(pair.rotations, times_a, times_b);
    if (!c.ok) return;  // the pair's gyro does not cover it: no verdict
    compensations.push_back(c.homographies);
  }
  const CompensationComparison comparison =
      compareCompensations(pair.camera, pair.matches, compensations, pair.gyro_homographies, options_.check);
  if (!comparison.usable) return;
  const std::shared_ptr<const LearnedStabiliser> trial = trials_->inUse();
  const auto outcome =
      trials_->addPair(comparison.residuals_px[0], comparison.residuals_px[1], comparison.gyro_residual_px);
  const std::string figures = trials_->evidence().summary();
  std::lock_guard<std::mutex> lock(mutex_);
  if (outcome.verdict == TrialVerdict::kPending) {
    status_.confirmation = "on trial: " + trial->name + ", " + std::to_string(trials_->evidence().pairs()) + " of " +
                           std::to_string(options_.confirmation.pairs) + " pairs checked";
    return;
  }
  // The verdict ends the swap's probation on the lens motions too (one verdict per swap).
  on_trial_ = false;
  replaced_.reset();
  confirm_requested_ = false;
  switch (outcome.verdict) {
    case TrialVerdict::kConfirmed:
      ++status_.swaps_confirmed;
      if (!outcome.persist_error.empty()) {
        ++status_.saves_failed;
        status_.last_problem = "saving the confirmed model: " + outcome.persist_error;
      } else if (!options_.model_path.empty()) {
        ++status_.saves;
      }
      status_.confirmation = "confirmed " + trial->name + " by the per-pair check (" + figures + ")" +
                             (options_.model_path.empty() ? "" : outcome.persist_error.empty() ? "; written"
                                                                                               : "; NOT written");
      break;
    case TrialVerdict::kKeptUnconfirmed:
      ++status_.swaps_kept_unconfirmed;
      status_.confirmation = "kept " + trial->name + " in use but not written: worse than the plain gyro (" +
                             figures + ")";
      break;
    case TrialVerdict::kUndone: {
      auto restored = std::make_shared<LearnedStabiliser>(*trials_->inUse());
      restored->version = model_->version + 1;
      restored->reason = "the swap to " + trial->name + " undone by the per-pair check (" + figures + ")";
      model_ = restored;
      ++status_.swaps;
      ++status_.swaps_undone;
      ++status_.swaps_undone_by_pairs;
      status_.confirmation = "undone " + trial->name + ", not written: worse than the model it replaced (" +
                             figures + ")";
      break;
    }
    case TrialVerdict::kPending:
      break;
  }
}

void OnlineStabiliserLearner::confirmSwap(const std::shared_ptr<const LearnedStabiliser>& replaced,
                                          const std::vector<std::shared_ptr<const Window>>& fresh) {
  std::vector<StabiliserFitRecording> held_out;
  for (const auto& w : fresh) held_out.push_back(w->recording);
  const std::shared_ptr<const LearnedStabiliser> current = model();
  const StabiliserChoice choice = chooseStabiliserModel(
      {{current->name + " (in use)", current->parameters}, {replaced->name + " (replaced)", replaced->parameters}},
      0, held_out, options_.choice);
  std::shared_ptr<LearnedStabiliser> restored;
  if (choice.replaced_incumbent) {
    restored = std::make_shared<LearnedStabiliser>(*replaced);
    restored->version = current->version + 1;
    restored->held_out_rms_px = choice.scores[1].rms_px;
    restored->held_out_rms_without_px = choice.scores[1].rms_without_model_px;
    restored->reason = "the swap to " + current->name + " undone: " + choice.reason;
  }
  // Undone only while the swap is still on trial (the per-pair check may have ended it meanwhile);
  // nothing is written: the file holds the last confirmed model.
  std::unique_lock<std::mutex> trials_lock(trials_mutex_);
  if (restored && !(trials_->onTrial() && trials_->inUse() == current)) restored.reset();
  if (restored) trials_->undo();
  std::lock_guard<std::mutex> lock(mutex_);
  status_.last_choice = "confirming the last swap: " + choice.reason;
  if (restored) {  // the fit thread is the only one that swaps: model_ is still `current`
    model_ = restored;
    ++status_.swaps;
    ++status_.swaps_undone;
    on_trial_ = false;
    status_.confirmation = "undone " + current->name + " on the lens motions after it, not written";
  }
}

}  // namespace deep_ois
