#include "deep_ois/core/online/clock_offset_filter.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

namespace {

// The learned mean starts at a scale of 1 worth this many windows (few windows say little).
constexpr double kPriorWindows = 2.0;
// The learned correlation of consecutive windows is kept below this (at most 9x a window's variance).
constexpr double kMaxCorrelation = 0.8;

}  // namespace

std::string ClockModelOptions::validate() const {
  std::ostringstream why;
  if (!(offset_random_walk_s_per_sqrt_s >= 0.0) || !(rate_random_walk_per_sqrt_s >= 0.0) ||
      !(initial_rate_sigma >= 0.0) ||
      !std::isfinite(offset_random_walk_s_per_sqrt_s + rate_random_walk_per_sqrt_s + initial_rate_sigma)) {
    why << "offset_random_walk_s_per_sqrt_s, rate_random_walk_per_sqrt_s and initial_rate_sigma must be finite and >= 0";
  } else if (!(jump_sigmas > 1.0) || !std::isfinite(jump_sigmas)) {
    why << "jump_sigmas must be above 1 (got " << jump_sigmas << ")";
  } else if (!(suspect_sigmas > 0.0 && suspect_sigmas <= jump_sigmas)) {
    why << "suspect_sigmas must be in (0, jump_sigmas] (got " << suspect_sigmas << ")";
  } else if (!(noise_memory >= 1.0) || !std::isfinite(noise_memory)) {
    why << "noise_memory must be at least 1 window (got " << noise_memory << ")";
  } else if (!(systematic_sigma_s >= 0.0) || !std::isfinite(systematic_sigma_s) || !(systematic_rate_sigma >= 0.0) ||
             !std::isfinite(systematic_rate_sigma)) {
    why << "systematic_sigma_s and systematic_rate_sigma must be finite and >= 0 (got " << systematic_sigma_s << ", "
        << systematic_rate_sigma << ")";
  } else if (!(min_noise_scale > 0.0 && min_noise_scale <= 1.0) || !(max_noise_scale >= 1.0) ||
             !std::isfinite(max_noise_scale)) {
    why << "min_noise_scale must be in (0, 1] and max_noise_scale at least 1 (got " << min_noise_scale << ", "
        << max_noise_scale << ")";
  }
  return why.str();
}

ClockOffsetFilter::ClockOffsetFilter(ClockModelOptions options) : options_(options) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("clock model: " + problem);
}

double ClockOffsetFilter::windowVariance(const ClockMeasurement& measurement) const {
  return std::pow(noise_scale_ * measurement.sigma_s, 2);
}

void ClockOffsetFilter::predict(double stamp_s, Eigen::Vector2d* state, Eigen::Matrix2d* covariance) const {
  const double dt = stamp_s - stamp_s_;
  const double elapsed = std::abs(dt);  // backwards (the window's middle before the last) grows it too
  Eigen::Matrix2d F;
  F << 1.0, dt, 0.0, 1.0;
  // A rate random walk integrated into the offset, plus the offset's own walk.
  const double q_rate = std::pow(options_.rate_random_walk_per_sqrt_s, 2);
  Eigen::Matrix2d Q;
  Q << q_rate * elapsed * elapsed * elapsed / 3.0 + std::pow(options_.offset_random_walk_s_per_sqrt_s, 2) * elapsed,
      q_rate * dt * elapsed / 2.0, q_rate * dt * elapsed / 2.0, q_rate * elapsed;
  *state = F * state_;
  *covariance = F * covariance_ * F.transpose() + Q;
}

double ClockOffsetFilter::offsetAt(double stamp_s) const {
  Eigen::Vector2d state;
  Eigen::Matrix2d covariance;
  predict(stamp_s, &state, &covariance);
  return state(0);
}

double ClockOffsetFilter::sigmaAt(double stamp_s) const {
  Eigen::Vector2d state;
  Eigen::Matrix2d covariance;
  predict(stamp_s, &state, &covariance);
  return std::sqrt(std::max(covariance(0, 0), 0.0) + options_.systematic_sigma_s * options_.systematic_sigma_s);
}

double ClockOffsetFilter::rateSigma() const {
  return std::sqrt(std::max(covariance_(1, 1), 0.0) + options_.systematic_rate_sigma * options_.systematic_rate_sigma);
}

void ClockOffsetFilter::restart(const ClockMeasurement& measurement, bool keep_rate) {
  const bool had_rate = keep_rate && initialised_;
  const double rate = had_rate ? state_(1) : 0.0;
  const double rate_variance = had_rate ? covariance_(1, 1) : std::pow(options_.initial_rate_sigma, 2);
  initialised_ = true;
  state_ = Eigen::Vector2d(measurement.offset_s, rate);
  covariance_ = Eigen::Vector2d(windowVariance(measurement), rate_variance).asDiagonal();
  stamp_s_ = measurement.stamp_s;
  last_normalised_innovation_ = 0.0;
}

bool ClockOffsetFilter::isJump(const ClockMeasurement& measurement, double sigmas) const {
  if (!initialised_) return false;
  Eigen::Vector2d state;
  Eigen::Matrix2d covariance;
  predict(measurement.stamp_s, &state, &covariance);
  // A single window's deviation: its own (scaled) variance, not the overlap's share.
  const double innovation = measurement.offset_s - state(0);
  return std::abs(innovation) > sigmas * std::sqrt(covariance(0, 0) + windowVariance(measurement));
}

ClockOffsetFilter::Outcome ClockOffsetFilter::add(const ClockMeasurement& measurement) {
  if (!std::isfinite(measurement.offset_s) || !std::isfinite(measurement.stamp_s) || !(measurement.sigma_s > 0.0) ||
      !(measurement.overlap >= 1.0)) {
    throw std::invalid_argument("clock model: a measurement needs a finite offset and stamp, a positive sigma and "
                                "an overlap of at least 1");
  }
  if (!initialised_) {
    restart(measurement);
    return Outcome::kStarted;
  }
  if (isJump(measurement)) return Outcome::kJump;
  Eigen::Vector2d state;
  Eigen::Matrix2d covariance;
  predict(measurement.stamp_s, &state, &covariance);
  const double innovation = measurement.offset_s - state(0);
  const double own_variance = windowVariance(measurement);
  last_normalised_innovation_ = innovation / std::sqrt(covariance(0, 0) + own_variance);

  // Covariance matching: E[innovation^2] = predicted variance + the window's error variance; and
  // the innovations' lag-1 correlation, which the windows' shared errors leave in them.
  const double sigma2 = measurement.sigma_s * measurement.sigma_s;
  const double excess = (innovation * innovation - covariance(0, 0)) / sigma2;
  const double square = innovation * innovation / sigma2;
  const double normalised = innovation / measurement.sigma_s;
  if (memory_weight_ == 0.0) {
    // The prior: the window's 1-sigma as reported, and the correlation overlapping windows have
    // (a window shares 1 - 1/overlap of its pairs with the next).
    mean_excess_ = 1.0;
    mean_square_ = 1.0;
    mean_lag_ = 1.0 - 1.0 / measurement.overlap;
    memory_weight_ = kPriorWindows;
  }
  const double decay = 1.0 - 1.0 / options_.noise_memory;
  memory_weight_ = memory_weight_ * decay + 1.0;
  mean_excess_ += (excess - mean_excess_) / memory_weight_;
  mean_square_ += (square - mean_square_) / memory_weight_;
  if (has_last_innovation_) mean_lag_ += (normalised * last_normalised_ - mean_lag_) / memory_weight_;
  last_normalised_ = normalised;
  has_last_innovation_ = true;
  noise_scale_ =
      std::clamp(std::sqrt(std::max(mean_excess_, 0.0)), options_.min_noise_scale, options_.max_noise_scale);
  correlation_ = std::clamp(mean_lag_ / std::max(mean_square_, 1e-12), 0.0, kMaxCorrelation);

  // Correlated windows carry less than one window's information each: the variance of a mean of
  // AR(1) errors is (1 + r) / (1 - r) times that of independent ones.
  const double measured_variance = windowVariance(measurement) * (1.0 + correlation_) / (1.0 - correlation_);
  const double innovation_variance = covariance(0, 0) + measured_variance;
  const Eigen::Vector2d gain = covariance.col(0) / innovation_variance;
  state_ = state + gain * innovation;
  covariance_ = covariance - gain * covariance.row(0);
  // Symmetric, as rounding may not keep it.
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();
  stamp_s_ = measurement.stamp_s;
  return Outcome::kFused;
}

}  // namespace deep_ois
