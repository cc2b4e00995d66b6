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
  } else if (max_tracks_per_pair < calibration.min_tracks_per_pair) {
    why << "max_tracks_per_pair (" << max_tracks_per_pair << ") must be at least calibration.min_tracks_per_pair ("
        << calibration.min_tracks_per_pair << ")";
  } else if (!(first_search_s > 0.0 && first_search_s <= 5.0) || !(search_s > 0.0 && search_s <= first_search_s)) {
    why << "first_search_s must be in (0, 5] s and search_s in (0, first_search_s] (got " << first_search_s << ", "
        << search_s << ")";
  } else if (!(offset_random_walk_s_per_sqrt_s >= 0.0) || !(rate_random_walk_per_sqrt_s >= 0.0) ||
             !(initial_rate_sigma >= 0.0) || !(readout_drift_s_per_s >= 0.0) || !(bias_drift_rad_s_per_s >= 0.0) ||
             !std::isfinite(offset_random_walk_s_per_sqrt_s + rate_random_walk_per_sqrt_s + initial_rate_sigma +
                            readout_drift_s_per_s + bias_drift_rad_s_per_s)) {
    why << "the random walks, initial_rate_sigma and the *_drift_*_per_s rates must be finite and >= 0";
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
  } else if (readout_every < 1) {
    why << "readout_every must be at least 1 (got " << readout_every << ")";
  } else if (!(jump_sigmas > 1.0)) {
    why << "jump_sigmas must be above 1 (got " << jump_sigmas << ")";
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

CalibrationData OnlineCalibrationEstimator::windowData(double begin_s, double end_s, double offset_s) const {
  CalibrationData data;
  data.camera = camera_;
  std::map<double, int> frame_of;
  for (const OnlineCalibrationPair& pair : pairs_) {
    if (pair.stamp_a_s < begin_s || pair.stamp_b_s > end_s) continue;
    frame_of.emplace(pair.stamp_a_s, 0);
    frame_of.emplace(pair.stamp_b_s, 0);
  }
  int index = 0;
  for (auto& [stamp, frame] : frame_of) {
    frame = index++;
    // The stamps are moved by the offset around which the search is centred.
    data.frame_stamps_s.push_back(stamp + offset_s);
  }
  for (const OnlineCalibrationPair& pair : pairs_) {
    if (pair.stamp_a_s < begin_s || pair.stamp_b_s > end_s) continue;
    CalibrationPair out;
    out.frame_a = frame_of.at(pair.stamp_a_s);
    out.frame_b = frame_of.at(pair.stamp_b_s);
    out.matches = pair.matches;
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
  if (jumped && std::abs(innovation) > options_.jump_sigmas * std::sqrt(predicted + measured_variance)) {
    *jumped = true;
    return false;
  }
  const double gain = predicted / (predicted + measured_variance);
  filter.value += gain * innovation;
  filter.variance = (1.0 - gain) * predicted;
  filter.stamp_s = stamp_s;
  return true;
}

void OnlineCalibrationEstimator::fit() {
  new_pairs_s_ = 0.0;
  const double end_s = last_pair_stamp_s_;
  const double begin_s = end_s - options_.window_s;
  // The window is calibrated around the estimate: its stamps are moved by the offset in use, so
  // the coarse grid [-search, +search] is centred there.
  const double centre_s = status_.estimate.time_offset_s;
  CalibrationData data = windowData(begin_s, end_s, centre_s);
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

  const auto started = std::chrono::steady_clock::now();
  CalibrationResult result;
  const std::size_t pairs_in_window = data.pairs.size();
  if (static_cast<int>(pairs_in_window) < options.min_pairs) {
    ++status_.fits_needing_motion;
    status_.state = "needs motion";
    std::ostringstream why;
    why << "needs motion: only " << pairs_in_window << " tracked pairs in the last " << options_.window_s
        << " s (at least " << options.min_pairs << " with " << options.min_tracks_per_pair
        << " tracks each): point the camera at a textured scene and move it";
    status_.last_reason = why.str();
    return;
  }
  try {
    result = calibrateCameraImu(data, options);
  } catch (const std::invalid_argument& error) {
    ++status_.fits_needing_motion;
    status_.state = "needs motion";
    status_.last_reason = std::string("needs motion: ") + error.what();
    return;
  }
  status_.last_fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  for (const std::string& refusal : result.refusals) {
    if (refusal.rfind("motion:", 0) == 0) {
      ++status_.fits_needing_motion;
      status_.state = "needs motion";
      status_.last_reason = "needs motion: " + refusal;
      return;
    }
  }
  const CameraImuCalibration& window = result.calibration;
  const double offset_s = window.time_offset_s + centre_s;
  std::ostringstream said;
  said << std::fixed << std::setprecision(3) << "window ending " << end_s << " s: offset " << offset_s * 1e3
       << " +- " << window.time_offset_sigma_s * 1e3 << " ms, readout " << window.readout_time_s * 1e3 << " +- "
       << window.readout_time_sigma_s * 1e3 << " ms";
  std::string rejected;
  if (!(window.time_offset_sigma_s <= options_.max_offset_sigma_s)) rejected = "the offset's 1-sigma is too wide";
  else if (!(window.readout_time_sigma_s <= options_.max_readout_sigma_s)) rejected = "the readout's 1-sigma is too wide";
  else if (options.estimate_gyro_bias && !(window.gyro_bias_sigma_rad_s.maxCoeff() <= options_.max_bias_sigma_rad_s)) {
    rejected = "the bias's 1-sigma is too wide";
  } else if (options.estimate_rotation && (!result.ok() || !(window.rotation_sigma_rad.maxCoeff() <=
                                                              options_.max_rotation_sigma_rad))) {
    rejected = "the mount is not determined by this window" + (result.ok() ? "" : " (" + result.reason() + ")");
  }
  if (!rejected.empty()) {
    ++status_.fits_rejected;
    status_.last_reason = said.str() + ": not used, " + rejected;
    return;
  }

  // The mount: confirmed when two consecutive accepted windows find the same permutation; then
  // only windows on that permutation count, and their small rotation is fused.
  bool restart = false;
  const double stamp_s = end_s - 0.5 * options_.window_s;
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

  bool jumped = false;
  if (!restart && offset_.initialised) {
    Eigen::Vector2d state;
    Eigen::Matrix2d covariance;
    predictOffset(offset_, stamp_s, &state, &covariance);
    const double offset_variance = std::pow(window.time_offset_sigma_s, 2);
    const double innovation = offset_s - state(0);
    const double innovation_variance = covariance(0, 0) + offset_variance;
    if (std::abs(innovation) > options_.jump_sigmas * std::sqrt(innovation_variance)) {
      jumped = true;
    } else {
      Filter readout = readout_;
      if (!hold_readout) {
        fuse(readout, window.readout_time_s, window.readout_time_sigma_s, options_.readout_drift_s_per_s, stamp_s,
             &jumped);
      }
      if (!jumped) {
        readout_ = readout;
        const Eigen::Vector2d gain = covariance.col(0) / innovation_variance;
        offset_.state = state + gain * innovation;
        offset_.covariance = covariance - gain * covariance.row(0);
        offset_.stamp_s = stamp_s;
      }
    }
  }
  if (restart || jumped || !offset_.initialised) {
    offset_.initialised = true;
    offset_.state = Eigen::Vector2d(offset_s, 0.0);
    offset_.covariance = Eigen::Vector2d(std::pow(window.time_offset_sigma_s, 2),
                                         std::pow(options_.initial_rate_sigma, 2)).asDiagonal();
    offset_.stamp_s = stamp_s;
    for (Filter& axis : bias_) axis = {};
    if (hold_readout) {
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
  // The offset carried to the newest pair (the window's middle is window_s / 2 behind it).
  Eigen::Vector2d offset_now;
  Eigen::Matrix2d offset_now_covariance;
  predictOffset(offset_, end_s, &offset_now, &offset_now_covariance);
  estimate.time_offset_s = offset_now(0);
  estimate.time_offset_sigma_s = std::sqrt(offset_now_covariance(0, 0));
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
       << " ms, readout " << estimate.readout_time_s * 1e3 << " +- " << estimate.readout_time_sigma_s * 1e3 << " ms";
  status_.last_reason = said.str();
  // Offered for use once the mount is known, after the pairs that follow this window.
  if (status_.mount_found) {
    candidate_ = estimate;
    candidate_rate_ = offset_now(1);
    candidate_waiting_ = true;
    candidate_after_s_ = end_s;
  }
}

void OnlineCalibrationEstimator::predictOffset(const OffsetFilter& filter, double stamp_s, Eigen::Vector2d* state,
                                               Eigen::Matrix2d* covariance) const {
  const double dt = std::max(stamp_s - filter.stamp_s, 0.0);
  Eigen::Matrix2d F;
  F << 1.0, dt, 0.0, 1.0;
  // A rate random walk integrated into the offset, plus the offset's own walk.
  const double q_rate = std::pow(options_.rate_random_walk_per_sqrt_s, 2);
  Eigen::Matrix2d Q;
  Q << q_rate * dt * dt * dt / 3.0 + std::pow(options_.offset_random_walk_s_per_sqrt_s, 2) * dt, q_rate * dt * dt / 2.0,
      q_rate * dt * dt / 2.0, q_rate * dt;
  *state = F * filter.state;
  *covariance = F * filter.covariance * F.transpose() + Q;
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
                                           const CameraImuCalibration& a, const CameraImuCalibration& b,
                                           double* a_px, double* b_px, int* tracks) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  *a_px = *b_px = nan;
  *tracks = 0;
  double sum_a = 0.0, sum_b = 0.0;
  for (const OnlineCalibrationPair& pair : pairs) {
    // Pair by pair, so that a track's two residuals are the same track's.
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
  // The candidate's offset is the filter's at its window's end; the filter's drift rate carries it
  // to the held-out pairs' middle for the score, and to the newest pair when it is applied.
  CameraImuCalibration scored = candidate_;
  scored.time_offset_s += candidate_rate_ * 0.5 * options_.held_out_s;
  candidate_.time_offset_s += candidate_rate_ * std::max(last_pair_stamp_s_ - candidate_after_s_, 0.0);
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
  bool refinement = !better && options_.refine_when_not_worse && tracks > 0 && !worse &&
                    outsideEstimate(status_.in_use, candidate_, false);
  if (!better && !refinement && options_.refine_when_not_worse && tracks > 0 && !worse &&
      outsideEstimate(status_.in_use, candidate_, true)) {
    // Only the offset is beyond refine_offset_s (a drift): the offset alone moves, the other
    // quantities stay within their intervals as they are; that calibration is scored too.
    CameraImuCalibration offset_only = status_.in_use;
    offset_only.time_offset_s = scored.time_offset_s;
    double unused_px = 0.0, offset_only_px = 0.0;
    int offset_only_tracks = 0;
    scorePair(held_out, status_.in_use, offset_only, &unused_px, &offset_only_px, &offset_only_tracks);
    const bool offset_only_worse = offset_only_px > in_use_px * (1.0 + options_.margins.min_relative_improvement) &&
                                   offset_only_px - in_use_px > options_.margins.min_improvement_px;
    if (offset_only_tracks > 0 && !offset_only_worse) {
      const CameraImuCalibration full = candidate_;
      candidate_ = status_.in_use;
      candidate_.time_offset_s = full.time_offset_s;
      candidate_.time_offset_sigma_s = full.time_offset_sigma_s;
      refinement = true;
    }
  }
  if (better || refinement) {
    status_.in_use = candidate_;
    ++status_.version;
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
