#include "deep_ois/core/online/online_calibration_estimator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <time.h>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// Seconds of gyro kept before the oldest buffered pair (the coarse search and the integrator's
// start need some on both sides).
constexpr double kGyroMarginS = 0.3;

double threadCpuS() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

std::string milliseconds(double seconds) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << seconds * 1e3 << " ms";
  return out.str();
}

}  // namespace

CalibrationOptions OnlineCalibrationOptions::defaultWindowCalibration() {
  CalibrationOptions options;
  // A window of a few seconds at 30 fps holds ~90 pairs; half of them must be tracked.
  options.min_pairs = 30;
  // A few seconds every second or two in the background: fewer iterations than the offline tool
  // (the window starts from the estimate, the steps become negligible in a handful).
  options.max_iterations = 20;
  return options;
}

std::string OnlineCalibrationOptions::validate() const {
  std::ostringstream why;
  if (!(window_s >= 0.5 && window_s <= 60.0)) {
    why << "window_s must be in [0.5, 60] seconds (got " << window_s << ")";
  } else if (!(refit_every_s > 0.0 && refit_every_s <= window_s)) {
    why << "refit_every_s must be in (0, window_s] seconds (got " << refit_every_s << ")";
  } else if (!(held_out_s > 0.0 && held_out_s <= 60.0)) {
    why << "held_out_s must be in (0, 60] seconds (got " << held_out_s << ")";
  } else if (max_pairs_per_window != 0 && max_pairs_per_window < calibration.min_pairs) {
    why << "max_pairs_per_window (" << max_pairs_per_window << ") must be 0 (every pair) or at least "
        << "calibration.min_pairs (" << calibration.min_pairs << ")";
  } else if (max_tracks_per_pair < calibration.min_tracks_per_pair) {
    why << "max_tracks_per_pair (" << max_tracks_per_pair << ") must be at least calibration.min_tracks_per_pair ("
        << calibration.min_tracks_per_pair << ")";
  } else if (!(first_search_s > 0.0 && first_search_s <= 5.0) || !(search_s > 0.0 && search_s <= first_search_s)) {
    why << "first_search_s must be in (0, 5] s and search_s in (0, first_search_s] (got " << first_search_s << ", "
        << search_s << ")";
  } else if (!(readout_drift_s_per_s >= 0.0) || !(bias_drift_rad_s_per_s >= 0.0) ||
             !std::isfinite(readout_drift_s_per_s + bias_drift_rad_s_per_s)) {
    why << "readout_drift_s_per_s and bias_drift_rad_s_per_s must be finite and >= 0";
  } else if (!clock.validate().empty()) {
    why << "clock: " << clock.validate();
  } else if (!(jump_window_s >= 0.0 && jump_window_s <= window_s)) {
    why << "jump_window_s must be in [0, window_s] seconds (got " << jump_window_s << ")";
  } else if (!(max_borrow_s >= 0.0) || !std::isfinite(max_borrow_s)) {
    why << "max_borrow_s must be finite and >= 0 (got " << max_borrow_s << ")";
  } else if (!(cpu_share >= 0.0 && cpu_share <= 1.0)) {
    why << "cpu_share must be in [0, 1] (got " << cpu_share << ")";
  } else if (rotation_every < 1) {
    why << "rotation_every must be at least 1 (got " << rotation_every << ")";
  } else if (!(refine_sigmas > 0.0)) {
    why << "refine_sigmas must be positive (got " << refine_sigmas << ")";
  } else if (!(refine_offset_s >= 0.0) || !(hold_readout_below_sigma_s >= 0.0) || !std::isfinite(refine_offset_s) ||
             !std::isfinite(hold_readout_below_sigma_s)) {
    why << "refine_offset_s and hold_readout_below_sigma_s must be finite and >= 0 (got " << refine_offset_s << ", "
        << hold_readout_below_sigma_s << ")";
  } else if (!(applied_rate_sigmas >= 0.0) || !std::isfinite(applied_rate_sigmas)) {
    why << "applied_rate_sigmas must be finite and >= 0 (got " << applied_rate_sigmas << ")";
  } else if (readout_every < 1) {
    why << "readout_every must be at least 1 (got " << readout_every << ")";
  } else if (!(max_offset_sigma_s > 0.0) || !(max_readout_sigma_s > 0.0) || !(max_bias_sigma_rad_s > 0.0) ||
             !(max_rotation_sigma_rad > 0.0)) {
    why << "the max_*_sigma limits must be positive";
  } else if (!(outlier_px > 0.0)) {
    why << "outlier_px must be positive (got " << outlier_px << ")";
  } else if (!(margins.min_relative_improvement >= 0.0) || !(margins.min_improvement_px >= 0.0)) {
    why << "margins.min_relative_improvement and margins.min_improvement_px must be >= 0";
  } else {
    const std::string calibration_problem = calibration.validate();
    if (!calibration_problem.empty()) why << "calibration: " << calibration_problem;
  }
  return why.str();
}

OnlineCalibrationEstimator::OnlineCalibrationEstimator(OnlineCalibrationOptions options, CameraModel camera,
                                                       CameraImuCalibration start)
    : options_(std::move(options)), camera_(std::move(camera)) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("online calibration: " + problem);
  clock_ = ClockOffsetFilter(options_.clock);
  const std::string camera_problem = camera_.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("online calibration: camera: " + camera_problem);
  if (!std::isfinite(start.time_offset_s) || !(start.readout_time_s >= 0.0 && start.readout_time_s <= 1.0) ||
      !start.gyro_bias_rad_s.allFinite() || !isProperRotation(start.imu_to_camera_rotation)) {
    throw std::invalid_argument(
        "online calibration: the starting calibration needs a finite time offset, a readout in [0, 1] s, a finite "
        "bias and a proper rotation");
  }
  status_.in_use = start;
  status_.estimate = start;
  rotation_ = start.imu_to_camera_rotation;
  status_.mount_found = !options_.estimate_rotation;
  status_.mount_permutation_index = nearestSignedAxisPermutation(rotation_);
}

void OnlineCalibrationEstimator::addGyro(const ImuSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.angular_velocity_rad_s.allFinite()) return;
  if (!gyro_.empty() && sample.stamp_s <= gyro_.back().stamp_s) return;
  gyro_.push_back(sample);
}

void OnlineCalibrationEstimator::addPair(OnlineCalibrationPair pair) {
  if (!std::isfinite(pair.stamp_a_s) || !std::isfinite(pair.stamp_b_s) || !(pair.stamp_b_s > pair.stamp_a_s)) return;
  if (pair.stamp_a_s < last_pair_stamp_s_) return;
  if (last_pair_stamp_s_ > -1e299) {
    const double elapsed_s = pair.stamp_b_s - std::max(last_pair_stamp_s_, pair.stamp_a_s);
    new_pairs_s_ += elapsed_s;
    status_.stream_s += elapsed_s;
    if (options_.cpu_share > 0.0) {
      credit_s_ = std::min(credit_s_ + options_.cpu_share * elapsed_s, options_.cpu_share * 10.0);
    }
  }
  last_pair_stamp_s_ = pair.stamp_b_s;
  ++status_.pairs;
  const int limit = options_.max_tracks_per_pair;
  if (static_cast<int>(pair.matches.size()) > limit) {
    // Evenly thinned: the tracker's order runs over the image cells, so a stride keeps the spread.
    std::vector<FeatureMatch> kept;
    kept.reserve(limit);
    const double stride = static_cast<double>(pair.matches.size()) / limit;
    for (int i = 0; i < limit; ++i) kept.push_back(pair.matches[static_cast<std::size_t>(i * stride)]);
    pair.matches.swap(kept);
  }
  if (static_cast<int>(pair.matches.size()) < options_.calibration.min_tracks_per_pair) {
    ++status_.pairs_without_tracks;
  } else {
    pairs_.push_back(std::move(pair));
  }
  const double keep_after_s = last_pair_stamp_s_ - options_.window_s - options_.held_out_s - options_.refit_every_s;
  while (!pairs_.empty() && pairs_.front().stamp_a_s < keep_after_s) pairs_.pop_front();
  const double oldest_s = pairs_.empty() ? keep_after_s : pairs_.front().stamp_a_s;
  const double offset_s = status_.estimate.time_offset_s;
  while (gyro_.size() > 2 && gyro_[1].stamp_s < oldest_s + offset_s - options_.first_search_s - kGyroMarginS) {
    gyro_.pop_front();
  }
}

void OnlineCalibrationEstimator::restartTimeline() {
  window_floor_s_ = -1e300;
  last_fit_end_s_ = -1e300;
  pairs_.clear();
  gyro_.clear();
  new_pairs_s_ = 0.0;
  last_pair_stamp_s_ = -1e300;
  candidate_waiting_ = false;
}

double OnlineCalibrationEstimator::gyroEnd() const { return gyro_.empty() ? -1e300 : gyro_.back().stamp_s; }

bool OnlineCalibrationEstimator::due() const {
  if (!(last_pair_stamp_s_ > -1e299)) return false;
  // The gyro must reach past the newest pair at any offset the search may find.
  const double needed_s = last_pair_stamp_s_ + status_.estimate.time_offset_s + options_.first_search_s + 0.05;
  if (gyroEnd() < needed_s) return false;
  if (candidate_waiting_ && last_pair_stamp_s_ >= candidate_after_s_ + options_.held_out_s) return true;
  return new_pairs_s_ >= options_.refit_every_s && withinBudget();
}

bool OnlineCalibrationEstimator::withinBudget() const {
  return !(options_.cpu_share > 0.0) || credit_s_ >= last_work_cpu_s_;
}

bool OnlineCalibrationEstimator::update() {
  if (new_pairs_s_ >= options_.refit_every_s && !withinBudget() && !budget_said_) {
    ++status_.fits_over_budget;
    budget_said_ = true;  // counted once per delayed fit
  }
  if (!due()) return false;
  const std::uint64_t before = status_.version;
  const double started = threadCpuS();
  work_started_cpu_s_ = started;
  if (candidate_waiting_ && last_pair_stamp_s_ >= candidate_after_s_ + options_.held_out_s) scoreCandidate();
  bool fitted = false;
  if (new_pairs_s_ >= options_.refit_every_s && withinBudget()) {
    fit();
    fitted = true;
    budget_said_ = false;
  }
  const double cpu_s = threadCpuS() - started;
  status_.cpu_s += cpu_s;
  if (options_.cpu_share > 0.0) credit_s_ -= cpu_s;
  if (fitted) last_work_cpu_s_ = cpu_s;
  return status_.version != before;
}

double OnlineCalibrationEstimator::shiftAt(double stamp_s, double offset_s) const {
  return clock_.initialised() ? clock_.offsetAt(stamp_s) : offset_s;
}

CalibrationData OnlineCalibrationEstimator::windowData(double begin_s, double end_s, double offset_s,
                                                       bool along_model) const {
  CalibrationData data;
  data.camera = camera_;
  begin_s = std::max(begin_s, window_floor_s_);
  std::vector<const OnlineCalibrationPair*> chosen;
  for (const OnlineCalibrationPair& pair : pairs_) {
    if (pair.stamp_a_s >= begin_s && pair.stamp_b_s <= end_s) chosen.push_back(&pair);
  }
  const std::size_t limit = static_cast<std::size_t>(options_.max_pairs_per_window);
  if (limit > 0 && chosen.size() > limit) {
    // Evenly thinned, counted back from the newest pair (which is always in).
    std::vector<const OnlineCalibrationPair*> thinned;
    const double stride = static_cast<double>(chosen.size()) / static_cast<double>(limit);
    for (std::size_t i = 0; i < limit; ++i) {
      thinned.push_back(chosen[chosen.size() - 1 - static_cast<std::size_t>(std::floor(i * stride))]);
    }
    std::reverse(thinned.begin(), thinned.end());
    chosen.swap(thinned);
  }
  std::map<double, int> frame_of;
  for (const OnlineCalibrationPair* pair : chosen) {
    frame_of.emplace(pair->stamp_a_s, 0);
    frame_of.emplace(pair->stamp_b_s, 0);
  }
  int index = 0;
  for (auto& [stamp, frame] : frame_of) {
    frame = index++;
    // The stamps are moved by the clock model's line (the drift removed inside the window), or by
    // the offset around which the search is centred: the fit measures what is left, constant.
    data.frame_stamps_s.push_back(stamp + (along_model ? shiftAt(stamp, offset_s) : offset_s));
  }
  for (const OnlineCalibrationPair* pair : chosen) {
    CalibrationPair out;
    out.frame_a = frame_of.at(pair->stamp_a_s);
    out.frame_b = frame_of.at(pair->stamp_b_s);
    out.matches = pair->matches;
    data.pairs.push_back(std::move(out));
  }
  for (const ImuSample& sample : gyro_) data.gyro.push_back(sample);
  return data;
}

bool OnlineCalibrationEstimator::fuse(Filter& filter, double value, double sigma, double drift_per_s,
                                      double stamp_s, bool* jumped) const {
  const double measured_variance = sigma * sigma;
  if (!filter.initialised) {
    filter = {true, value, measured_variance, stamp_s};
    return true;
  }
  const double elapsed_s = std::max(stamp_s - filter.stamp_s, 0.0);
  const double predicted = filter.variance + std::pow(drift_per_s * elapsed_s, 2);
  const double innovation = value - filter.value;
  if (jumped && std::abs(innovation) > options_.clock.jump_sigmas * std::sqrt(predicted + measured_variance)) {
    *jumped = true;
    return false;
  }
  const double gain = predicted / (predicted + measured_variance);
  filter.value += gain * innovation;
  filter.variance = (1.0 - gain) * predicted;
  filter.stamp_s = stamp_s;
  return true;
}

OnlineCalibrationEstimator::ModelState OnlineCalibrationEstimator::modelState() const {
  ModelState state;
  state.clock = clock_;
  state.readout = readout_;
  for (int axis = 0; axis < 3; ++axis) state.bias[axis] = bias_[axis];
  state.rotation = rotation_;
  state.rotation_variance = rotation_variance_;
  state.last_permutation = last_permutation_;
  state.any_accepted = any_accepted_;
  state.mount_found = status_.mount_found;
  state.mount_permutation_index = status_.mount_permutation_index;
  state.window_floor_s = window_floor_s_;
  state.estimate = status_.estimate;
  state.in_use = status_.in_use;
  return state;
}

bool OnlineCalibrationEstimator::rewindBeforeSwap(std::uint64_t version) {
  auto found = std::find_if(swaps_.begin(), swaps_.end(), [&](const Remembered& r) { return r.version == version; });
  if (found == swaps_.end()) return false;
  const ModelState& state = found->before;
  clock_ = state.clock;
  readout_ = state.readout;
  for (int axis = 0; axis < 3; ++axis) bias_[axis] = state.bias[axis];
  rotation_ = state.rotation;
  rotation_variance_ = state.rotation_variance;
  last_permutation_ = state.last_permutation;
  any_accepted_ = state.any_accepted;
  status_.mount_found = state.mount_found;
  status_.mount_permutation_index = state.mount_permutation_index;
  window_floor_s_ = state.window_floor_s;
  status_.estimate = state.estimate;
  status_.in_use = state.in_use;
  status_.offset_noise_scale = clock_.noiseScale();
  // What the undone swap's fit (and any later one) offered is gone with it.
  candidate_waiting_ = false;
  swaps_.erase(found, swaps_.end());
  ++status_.rewinds;
  status_.last_reason = "rewound to before the fit that offered version " + std::to_string(version) +
                        " (undone): offset " + milliseconds(status_.estimate.time_offset_s) + " in use " +
                        milliseconds(status_.in_use.time_offset_s);
  return true;
}

// One window's calibration: the fit and the checks of its result; false (with the reason said)
// when it says nothing (too few pairs, no motion, an interval too wide).
bool OnlineCalibrationEstimator::calibrateWindow(const CalibrationData& data, const CalibrationOptions& options,
                                                 const std::string& label, CalibrationResult* result,
                                                 std::string* rejected) {
  rejected->clear();
  const std::size_t pairs_in_window = data.pairs.size();
  if (static_cast<int>(pairs_in_window) < options.min_pairs) {
    ++status_.fits_needing_motion;
    status_.state = "needs motion";
    std::ostringstream why;
    why << "needs motion: only " << pairs_in_window << " tracked pairs in the " << label << " (at least "
        << options.min_pairs << " with " << options.min_tracks_per_pair
        << " tracks each): point the camera at a textured scene and move it";
    status_.last_reason = why.str();
    return false;
  }
  const auto started = std::chrono::steady_clock::now();
  try {
    *result = calibrateCameraImu(data, options);
  } catch (const std::invalid_argument& error) {
    ++status_.fits_needing_motion;
    status_.state = "needs motion";
    status_.last_reason = std::string("needs motion: ") + error.what();
    return false;
  }
  status_.last_fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  for (const std::string& refusal : result->refusals) {
    if (refusal.rfind("motion:", 0) == 0) {
      ++status_.fits_needing_motion;
      status_.state = "needs motion";
      status_.last_reason = "needs motion: " + refusal;
      return false;
    }
  }
  const CameraImuCalibration& window = result->calibration;
  if (!(window.time_offset_sigma_s <= options_.max_offset_sigma_s)) {
    *rejected = "the offset's 1-sigma is too wide";
  } else if (options.estimate_readout_time && !(window.readout_time_sigma_s <= options_.max_readout_sigma_s)) {
    *rejected = "the readout's 1-sigma is too wide";
  } else if (options.estimate_gyro_bias && !(window.gyro_bias_sigma_rad_s.maxCoeff() <= options_.max_bias_sigma_rad_s)) {
    *rejected = "the bias's 1-sigma is too wide";
  } else if (options.estimate_rotation &&
             (!result->ok() || !(window.rotation_sigma_rad.maxCoeff() <= options_.max_rotation_sigma_rad))) {
    *rejected = "the mount is not determined by this window" + (result->ok() ? "" : " (" + result->reason() + ")");
  }
  return true;
}

void OnlineCalibrationEstimator::fit() {
  new_pairs_s_ = 0.0;
  candidate_before_ = modelState();
  const double end_s = last_pair_stamp_s_;
  const double begin_s = std::max(end_s - options_.window_s, window_floor_s_);
  // The window is calibrated around the clock model's line: its stamps are moved by it, so the
  // coarse grid [-search, +search] is centred there and the drift is removed inside the window.
  const double centre_s = status_.estimate.time_offset_s;
  CalibrationData data = windowData(begin_s, end_s, centre_s, true);
  ++status_.fits;
  CalibrationOptions options = options_.calibration;
  options.estimate_time_offset = true;
  options.time_offset_s = 0.0;
  options.max_abs_time_offset_s = any_accepted_ ? options_.search_s : options_.first_search_s;
  options.coarse_time_step_s = std::min(options.coarse_time_step_s, options.max_abs_time_offset_s);
  // The readout is held at its filtered value once the filter knows it (the window then measures
  // the offset alone, off the offset-readout ridge), except on every readout_every-th window.
  const bool hold_readout = status_.mount_found && readout_.initialised &&
                            std::sqrt(readout_.variance) <= options_.hold_readout_below_sigma_s &&
                            status_.fits % options_.readout_every != 1 % options_.readout_every;
  options.estimate_readout_time = !hold_readout;
  options.readout_time_s = hold_readout ? std::max(readout_.value, 0.0) : status_.estimate.readout_time_s;
  options.estimate_gyro_bias = options_.estimate_gyro_bias;
  options.gyro_bias_rad_s = status_.estimate.gyro_bias_rad_s;
  // Once the mount is found, its small rotation is refined on every rotation_every-th window only
  // (the rotation search costs about as much again as the rest of a window).
  options.estimate_rotation =
      options_.estimate_rotation && (!status_.mount_found || status_.fits % options_.rotation_every == 0);
  options.imu_to_camera_rotation = rotation_;
  options.lens_shift = options_.lens_shift;
  // The window's own refusal limits are the offline tool's for one recording; here a window's
  // estimate is a measurement weighed by its sigma (the max_*_sigma options below), so only the
  // refusals for motion and for a mount the data do not determine count.
  options.max_time_offset_sigma_s = options.max_readout_time_sigma_s = 1e9;
  options.max_rotation_sigma_rad = options.max_gyro_bias_sigma_rad_s = 1e9;

  CalibrationResult result;
  std::string rejected;
  std::ostringstream window_label;
  window_label << "last " << end_s - begin_s << " s";
  if (!calibrateWindow(data, options, window_label.str(), &result, &rejected)) return;
  CameraImuCalibration window = result.calibration;
  // The middle of the window: the drift was removed along the line, so what the window measured
  // is the line there moved by the window's constant.
  double stamp_s = 0.5 * (begin_s + end_s);
  double offset_s = window.time_offset_s + shiftAt(stamp_s, centre_s);
  std::ostringstream said;
  said << std::fixed << std::setprecision(3) << "window ending " << end_s << " s: offset " << offset_s * 1e3
       << " +- " << window.time_offset_sigma_s * 1e3 << " ms, readout " << window.readout_time_s * 1e3 << " +- "
       << window.readout_time_sigma_s * 1e3 << " ms";
  if (!rejected.empty()) {
    ++status_.fits_rejected;
    status_.last_reason = said.str() + ": not used, " + rejected;
    return;
  }

  // The mount: confirmed when two consecutive accepted windows find the same permutation; then
  // only windows on that permutation count, and their small rotation is fused.
  bool restart = false;
  if (options.estimate_rotation) {
    const int permutation = nearestSignedAxisPermutation(window.imu_to_camera_rotation);
    if (status_.mount_found && permutation != status_.mount_permutation_index) {
      ++status_.fits_rejected;
      status_.last_reason = said.str() + ": not used, its mount is axis permutation " + std::to_string(permutation) +
                            ", not the one found (" + std::to_string(status_.mount_permutation_index) + ")";
      return;
    }
    if (!status_.mount_found && permutation != last_permutation_) {
      // Another mount is another world: what was fused under the last one is dropped.
      restart = last_permutation_ >= 0;
      last_permutation_ = permutation;
      rotation_ = window.imu_to_camera_rotation;
      rotation_variance_ = window.rotation_sigma_rad.cwiseAbs2();
    } else {
      if (!status_.mount_found) said << ", mount found (axis permutation " << permutation << ")";
      status_.mount_found = true;
      const Eigen::Vector3d difference = logSO3(window.imu_to_camera_rotation * rotation_.transpose());
      Eigen::Vector3d gain;
      for (int axis = 0; axis < 3; ++axis) {
        const double measured = std::pow(window.rotation_sigma_rad(axis), 2);
        gain(axis) = rotation_variance_(axis) / (rotation_variance_(axis) + measured);
        rotation_variance_(axis) *= 1.0 - gain(axis);
      }
      rotation_ = expSO3(gain.cwiseProduct(difference)) * rotation_;
    }
    status_.mount_permutation_index = permutation;
  }

  // Overlapping windows share their pairs: this one counts for the share of it that is new.
  const double overlap = std::max(1.0, (end_s - begin_s) / std::max(end_s - last_fit_end_s_, 1e-3));
  last_fit_end_s_ = end_s;
  ClockMeasurement measured{stamp_s, offset_s, window.time_offset_sigma_s, overlap};
  status_.window_stamp_s = stamp_s;
  status_.window_offset_s = offset_s;
  status_.window_offset_sigma_s = window.time_offset_sigma_s;
  ++status_.windows_measured;
  // A window far from the line (suspect_sigmas) may hold a jump: the newest pairs are fitted at
  // once (ahead of the budget, within max_borrow_s) and tell. A window straddling a jump is wide
  // and lies between the two offsets; the newest pairs are after it.
  bool jumped = false;
  bool newest_measured_readout = !hold_readout;
  const bool suspect = !restart && clock_.initialised() && clock_.isJump(measured, options_.clock.suspect_sigmas);
  bool newest_said = false;
  if (suspect && options_.jump_window_s > 0.0) {
    const double newest_begin_s = end_s - options_.jump_window_s;
    const double owed_s = threadCpuS() - work_started_cpu_s_ - credit_s_;
    if (!(options_.cpu_share > 0.0) || owed_s < options_.max_borrow_s) {
      if (options_.cpu_share > 0.0 && owed_s > 0.0) ++status_.fits_borrowed;
      CalibrationOptions newest_options = options;
      newest_options.estimate_rotation = false;  // the mount does not jump with the clock
      newest_options.imu_to_camera_rotation = rotation_;
      newest_options.min_pairs = std::min(options.min_pairs, 20);
      const CalibrationData newest = windowData(newest_begin_s, end_s, offset_s, false);
      CalibrationResult newest_result;
      std::string newest_rejected;
      ++status_.fits;
      if (calibrateWindow(newest, newest_options, "newest " + std::to_string(options_.jump_window_s) + " s",
                          &newest_result, &newest_rejected) &&
          newest_rejected.empty()) {
        newest_said = true;
        const CameraImuCalibration& found = newest_result.calibration;
        const ClockMeasurement newest_measured{0.5 * (newest_begin_s + end_s), found.time_offset_s + offset_s,
                                               found.time_offset_sigma_s, 1.0};
        said << "; the newest " << options_.jump_window_s << " s: offset " << newest_measured.offset_s * 1e3 << " +- "
             << found.time_offset_sigma_s * 1e3 << " ms";
        if (clock_.isJump(newest_measured, options_.clock.jump_sigmas)) {
          // A jump: the filter restarts from the newest pairs, and older pairs leave the window.
          jumped = true;
          window = found;
          stamp_s = newest_measured.stamp_s;
          offset_s = newest_measured.offset_s;
          measured = newest_measured;
          newest_measured_readout = newest_options.estimate_readout_time;
          window_floor_s_ = newest_begin_s;
        }
      }
    }
  }
  if (suspect && !newest_said) jumped = clock_.isJump(measured, options_.clock.jump_sigmas);
  if (!restart && clock_.initialised() && !jumped) {
    Filter readout = readout_;
    if (!hold_readout) {
      fuse(readout, window.readout_time_s, window.readout_time_sigma_s, options_.readout_drift_s_per_s, stamp_s,
           &jumped);
    }
    if (!jumped) {
      readout_ = readout;
      clock_.add(measured);
    }
  }
  if (restart || jumped || !clock_.initialised()) {
    // A jump moves the offset, not the clocks' rates: the drift rate learned so far is kept.
    clock_.restart(measured, jumped);
    for (Filter& axis : bias_) axis = {};
    if (!newest_measured_readout) {
      // The window did not measure the readout: the filter keeps its value, widened so that the
      // next windows measure it again (a restarted camera app may have changed the mode).
      readout_.variance = std::max(readout_.variance, std::pow(2.0 * options_.hold_readout_below_sigma_s, 2));
    } else {
      readout_ = {};
      fuse(readout_, window.readout_time_s, window.readout_time_sigma_s, 0.0, stamp_s, nullptr);
    }
    if (jumped) {
      ++status_.jumps;
      said << ", a jump from " << milliseconds(status_.estimate.time_offset_s) << ": the estimate restarts here";
    }
  }
  if (options.estimate_gyro_bias) {
    for (int axis = 0; axis < 3; ++axis) {
      fuse(bias_[axis], window.gyro_bias_rad_s(axis), window.gyro_bias_sigma_rad_s(axis),
           options_.bias_drift_rad_s_per_s, stamp_s, nullptr);
    }
  }
  any_accepted_ = true;
  status_.state = jumped ? "jump" : (status_.mount_found ? "tracking" : "converging");

  CameraImuCalibration& estimate = status_.estimate;
  // The offset carried along the line to the newest pair.
  estimate.time_offset_s = clock_.offsetAt(end_s);
  estimate.time_offset_sigma_s = clock_.sigmaAt(end_s);
  const bool rate_told = std::abs(clock_.rate()) > options_.applied_rate_sigmas * clock_.rateSigma();
  estimate.time_offset_rate = options_.apply_drift_rate && rate_told ? clock_.rate() : 0.0;
  estimate.time_offset_reference_s = end_s;
  status_.offset_noise_scale = clock_.noiseScale();
  status_.window_correlation = clock_.windowCorrelation();
  estimate.readout_time_s = std::max(readout_.value, 0.0);
  estimate.readout_time_sigma_s = std::sqrt(readout_.variance);
  if (options.estimate_gyro_bias) {
    for (int axis = 0; axis < 3; ++axis) {
      estimate.gyro_bias_rad_s(axis) = bias_[axis].value;
      estimate.gyro_bias_sigma_rad_s(axis) = std::sqrt(bias_[axis].variance);
    }
  }
  estimate.imu_to_camera_rotation = rotation_;
  estimate.rotation_sigma_rad = rotation_variance_.cwiseSqrt();
  said << "; estimate offset " << estimate.time_offset_s * 1e3 << " +- " << estimate.time_offset_sigma_s * 1e3
       << " ms (windows' 1-sigma x " << std::setprecision(2) << clock_.noiseScale() << std::setprecision(3)
       << "), readout " << estimate.readout_time_s * 1e3 << " +- " << estimate.readout_time_sigma_s * 1e3 << " ms";
  status_.last_reason = said.str();
  // Offered for use once the mount is known, after the pairs that follow this window.
  if (status_.mount_found) {
    candidate_ = estimate;
    candidate_rate_ = clock_.rate();
    candidate_waiting_ = true;
    candidate_after_s_ = end_s;
  }
}

bool OnlineCalibrationEstimator::outsideEstimate(const CameraImuCalibration& in_use,
                                                 const CameraImuCalibration& estimate) const {
  return outsideEstimate(in_use, estimate, true);
}

bool OnlineCalibrationEstimator::outsideEstimate(const CameraImuCalibration& in_use, const CameraImuCalibration& estimate,
                                                 bool offset_threshold) const {
  const double k = options_.refine_sigmas;
  const double offset_difference_s = std::abs(in_use.time_offset_s - estimate.time_offset_s);
  if (offset_difference_s > k * estimate.time_offset_sigma_s) return true;
  if (offset_threshold && options_.refine_offset_s > 0.0 && offset_difference_s > options_.refine_offset_s) return true;
  if (std::abs(in_use.readout_time_s - estimate.readout_time_s) > k * estimate.readout_time_sigma_s) return true;
  if (options_.estimate_gyro_bias) {
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(in_use.gyro_bias_rad_s(axis) - estimate.gyro_bias_rad_s(axis)) >
          k * estimate.gyro_bias_sigma_rad_s(axis)) {
        return true;
      }
    }
  }
  if (options_.estimate_rotation) {
    const Eigen::Vector3d difference =
        logSO3(in_use.imu_to_camera_rotation * estimate.imu_to_camera_rotation.transpose()).cwiseAbs();
    for (int axis = 0; axis < 3; ++axis) {
      if (difference(axis) > k * estimate.rotation_sigma_rad(axis)) return true;
    }
  }
  return false;
}

void OnlineCalibrationEstimator::scorePair(const std::vector<OnlineCalibrationPair>& pairs,
                                           const CameraImuCalibration& a_line, const CameraImuCalibration& b_line,
                                           double* a_px, double* b_px, int* tracks) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  *a_px = *b_px = nan;
  *tracks = 0;
  double sum_a = 0.0, sum_b = 0.0;
  for (const OnlineCalibrationPair& pair : pairs) {
    // Pair by pair, so that a track's two residuals are the same track's; a drifting calibration
    // with its offset at the pair.
    const CameraImuCalibration a = a_line.heldAt(pair.stamp_a_s), b = b_line.heldAt(pair.stamp_a_s);
    CalibrationData data;
    data.camera = camera_;
    data.frame_stamps_s = {pair.stamp_a_s, pair.stamp_b_s};
    data.pairs.push_back({0, 1, pair.matches});
    for (const ImuSample& sample : gyro_) {
      const double lo = pair.stamp_a_s + std::min(a.time_offset_s, b.time_offset_s) - 0.1;
      const double hi = pair.stamp_b_s + std::max(a.time_offset_s, b.time_offset_s) + 0.2;
      if (sample.stamp_s >= lo && sample.stamp_s <= hi) data.gyro.push_back(sample);
    }
    if (data.gyro.size() < 2) continue;
    const std::vector<double> residual_a = trackResidualsPx(data, a);
    const std::vector<double> residual_b = trackResidualsPx(data, b);
    if (residual_a.size() != residual_b.size()) continue;  // one of them not covered by the gyro
    for (std::size_t i = 0; i < residual_a.size(); ++i) {
      if (std::min(residual_a[i], residual_b[i]) > options_.outlier_px) continue;
      sum_a += residual_a[i];
      sum_b += residual_b[i];
      ++*tracks;
    }
  }
  if (*tracks > 0) {
    *a_px = sum_a / *tracks;
    *b_px = sum_b / *tracks;
  }
}

void OnlineCalibrationEstimator::scoreCandidate() {
  candidate_waiting_ = false;
  std::vector<OnlineCalibrationPair> held_out;
  for (const OnlineCalibrationPair& pair : pairs_) {
    if (pair.stamp_a_s >= candidate_after_s_ && pair.stamp_b_s <= candidate_after_s_ + options_.held_out_s + 0.05) {
      held_out.push_back(pair);
    }
  }
  // The candidate's offset is the filter's at its window's end.
  CameraImuCalibration scored = candidate_;
  if (candidate_.time_offset_rate != 0.0) {
    // A line (the filter's drift rate): scored with its offset at each held-out pair, applied
    // as the same line referred to the newest pair.
    candidate_.time_offset_s = candidate_.timeOffsetAt(last_pair_stamp_s_);
    candidate_.time_offset_reference_s = last_pair_stamp_s_;
  } else {
    // A constant: the drift rate carries it to the held-out pairs' middle for the score. Applied,
    // it stays until the next swap (at least one held-out wait later): carried that far ahead
    // again, so that the drift leaves it half as far behind at the worst.
    scored.time_offset_s += candidate_rate_ * 0.5 * options_.held_out_s;
    candidate_.time_offset_s +=
        candidate_rate_ * (std::max(last_pair_stamp_s_ - candidate_after_s_, 0.0) + 0.5 * options_.held_out_s);
  }
  // Whether the candidate is outside the estimate's interval around the calibration in use, both
  // taken at the newest pair (where it would be applied) along their lines. Not further ahead:
  // the drift rates of two lines differ by the rate's noise, and a difference only the future
  // shows refines the other quantities too on a right calibration (the readout wandered 0.8 ms in
  // 15 s from a right start, test_online_calibration's KeepsARightCalibration); comparing the
  // offset alone ahead as well measured no better (docs/results/online_learning.md).
  const auto outside = [&](bool offset_threshold) {
    return outsideEstimate(status_.in_use.heldAt(last_pair_stamp_s_), candidate_.heldAt(last_pair_stamp_s_),
                           offset_threshold);
  };
  double in_use_px = 0.0, candidate_px = 0.0;
  int tracks = 0;
  scorePair(held_out, status_.in_use, scored, &in_use_px, &candidate_px, &tracks);
  ++status_.candidates_scored;
  status_.held_out_in_use_px = in_use_px;
  status_.held_out_candidate_px = candidate_px;
  std::ostringstream said;
  said << std::fixed << std::setprecision(4) << "held-out " << held_out.size() << " pairs, " << tracks
       << " tracks: candidate " << candidate_px << " px against " << in_use_px << " px in use";
  const bool better = tracks > 0 && candidate_px < in_use_px * (1.0 - options_.margins.min_relative_improvement) &&
                      in_use_px - candidate_px > options_.margins.min_improvement_px;
  // Worse by the same margins the other way round.
  const bool worse = candidate_px > in_use_px * (1.0 + options_.margins.min_relative_improvement) &&
                     candidate_px - in_use_px > options_.margins.min_improvement_px;
  bool refinement = !better && options_.refine_when_not_worse && tracks > 0 && !worse && outside(false);
  if (!better && !refinement && options_.refine_when_not_worse && tracks > 0 && !worse && outside(true)) {
    // Only the offset is beyond refine_offset_s (a drift): the offset alone moves, the other
    // quantities stay within their intervals as they are; that calibration is scored too.
    CameraImuCalibration offset_only = status_.in_use;
    offset_only.time_offset_s = scored.time_offset_s;
    offset_only.time_offset_rate = scored.time_offset_rate;
    offset_only.time_offset_reference_s = scored.time_offset_reference_s;
    double unused_px = 0.0, offset_only_px = 0.0;
    int offset_only_tracks = 0;
    scorePair(held_out, status_.in_use, offset_only, &unused_px, &offset_only_px, &offset_only_tracks);
    const bool offset_only_worse = offset_only_px > in_use_px * (1.0 + options_.margins.min_relative_improvement) &&
                                   offset_only_px - in_use_px > options_.margins.min_improvement_px;
    if (offset_only_tracks > 0 && !offset_only_worse) {
      const CameraImuCalibration full = candidate_;
      candidate_ = status_.in_use;
      candidate_.time_offset_s = full.time_offset_s;
      candidate_.time_offset_rate = full.time_offset_rate;
      candidate_.time_offset_reference_s = full.time_offset_reference_s;
      candidate_.time_offset_sigma_s = full.time_offset_sigma_s;
      refinement = true;
    }
  }
  if (better || refinement) {
    candidate_before_.in_use = status_.in_use;
    status_.in_use = candidate_;
    ++status_.version;
    swaps_.push_back({status_.version, candidate_before_});
    if (swaps_.size() > kRememberedSwaps) swaps_.pop_front();
    ++status_.swaps;
    if (refinement) ++status_.refinements;
    said << (better ? ": swapped (offset " : ": refined, no worse and outside the estimate's interval (offset ")
         << milliseconds(candidate_.time_offset_s) << ", readout " << milliseconds(candidate_.readout_time_s) << ")";
  } else {
    said << ": kept the calibration in use (not better by " << options_.margins.min_relative_improvement * 100
         << " % and " << options_.margins.min_improvement_px << " px)";
  }
  status_.last_reason = said.str();
}

}  // namespace deep_ois
