// The camera-IMU clock model of the online calibration: the time offset (IMU time = camera stamp +
// offset) is a line, offset(t) = offset + rate * (t - stamp), whose offset and drift rate (s/s)
// walk randomly (a constant-velocity Kalman filter); each calibration window measures the offset
// at its middle with a reported 1-sigma.
//
// What makes its 1-sigma honest:
//  - Overlapping windows share their pairs, so their errors are not independent: before it is
//    learned, the correlation of consecutive windows is taken as the share of pairs they have in
//    common (1 - 1 / overlap, `overlap` the number of windows a pair falls in).
//  - A window's own 1-sigma misses what its stretch of motion shares (the parallax of that
//    scene, a lens-shift misfit): its actual error was 2x its 1-sigma for several windows in a
//    row on the simulator. The filter learns the scale from its innovations (covariance
//    matching: the innovation's mean square minus the prediction's variance is the windows' error
//    variance), averaged over the last `noise_memory` windows and kept within [min_noise_scale,
//    max_noise_scale], and it learns how much consecutive windows' errors are alike (their
//    innovations' lag-1 correlation r): a window then counts for (1 - r) / (1 + r) of one.
//  - Part of a window's error is shared by every window of a recording for tens of seconds (the
//    scene's parallax, the lens model's misfit, the offset-readout ridge): on the simulator the
//    windows of one 60 s recording were off by -0.12 to +0.19 ms on average (seed 1). The innovations
//    cannot show it (the filter takes it for the offset), and no number of windows averages it
//    away, so the reported 1-sigma adds systematic_sigma_s to the filter's in quadrature.
//  - The reported 1-sigma is the filter's, carried to the moment it is asked for, with that floor.
//
// A jump: a window further than `jump_sigmas` combined sigmas (the prediction's and the window's
// own, scaled) from the prediction is not fused; the caller re-estimates from the newest window and
// restarts the filter there (restart()).
//
// Pure Eigen; not thread-safe (the estimator owns it).
#pragma once

#include <Eigen/Core>
#include <string>

namespace deep_ois {

struct ClockModelOptions {
  // The offset walks by offset_random_walk_s_per_sqrt_s (s per sqrt(s)) and the rate by
  // rate_random_walk_per_sqrt_s (s/s per sqrt(s)); the rate starts at 0 with initial_rate_sigma
  // (s/s: 1e-4 = 6 ms a minute). Small walks make the line a fit over many windows (the rate's
  // walk of 5e-6 lets it change by 2.3 ms a minute in a minute, 1-sigma): a window's error, 0.1-0.25 ms
  // and alike for neighbours, then moves the line much less than with 3e-5 and 1.5e-5, which
  // let the rate swing between 20 and 90 us/s around a true 50 (benchmark_online_calibration,
  // drift, seed 1). A jump is not a walk: it is told apart and restarts the line.
  double offset_random_walk_s_per_sqrt_s = 1.5e-5;
  double rate_random_walk_per_sqrt_s = 5e-6;
  double initial_rate_sigma = 1e-4;
  // A window further than this many combined sigmas from the prediction is a jump; beyond
  // suspect_sigmas it may be one (the estimator then checks the newest pairs).
  double jump_sigmas = 5.0;
  double suspect_sigmas = 3.0;
  // Windows over which the innovations' mean square is averaged (an exponential memory), and the
  // bounds of the learned scale of the windows' 1-sigma (below 1: the windows overstate it, as
  // the calibration's 1-sigma, inflated for a whole recording's systematic errors, does).
  double noise_memory = 10.0;
  double min_noise_scale = 0.3;
  double max_noise_scale = 4.0;
  // The windows' error that persists over a recording (seconds), added in quadrature to the
  // reported 1-sigma (sigmaAt), not to the filter's own covariance.
  // 0.12 ms brings the estimate's 1-sigma coverage on the drift runs of seed 1 from 49 % to 66 %.
  double systematic_sigma_s = 0.12e-3;
  // The same shared error seen as a drift rate (s/s): windows off alike by ~0.12 ms for 10-20 s
  // make a line lean by ~10 us/s on a steady clock (benchmark_online_calibration, jump, seed 1: a
  // learned 17-24 us/s against a true 0). Added in quadrature to the rate's 1-sigma (rateSigma).
  double systematic_rate_sigma = 1e-5;
  std::string validate() const;  // empty when usable, else a sentence naming the bad field
};

// One window's measurement of the offset.
struct ClockMeasurement {
  double stamp_s = 0.0;   // camera clock: where the window measures the offset (its middle)
  double offset_s = 0.0;  // IMU time = camera stamp + offset
  double sigma_s = 0.0;   // the window's reported 1-sigma
  double overlap = 1.0;   // windows sharing a pair (>= 1)
};

class ClockOffsetFilter {
 public:
  enum class Outcome { kStarted, kFused, kJump };

  explicit ClockOffsetFilter(ClockModelOptions options = {});

  bool initialised() const { return initialised_; }
  // Fuses a window (the first one starts the filter). kJump: too far from the prediction, nothing
  // changed (the learned scale neither).
  Outcome add(const ClockMeasurement& measurement);
  // Whether `measurement` is further than `sigmas` combined sigmas from the prediction (no change).
  bool isJump(const ClockMeasurement& measurement, double sigmas) const;
  bool isJump(const ClockMeasurement& measurement) const { return isJump(measurement, options_.jump_sigmas); }
  // Starts again from one window: the offset from it; the rate 0 with initial_rate_sigma, or with
  // keep_rate (a jump moves the offset, not the clocks' rates) the rate and its variance as they
  // are. The learned scale and correlation stay (they are the windows', not the clock's).
  void restart(const ClockMeasurement& measurement, bool keep_rate = false);
  // Offset (s) and drift rate (s/s) carried to stamp_s, with their covariance.
  void predict(double stamp_s, Eigen::Vector2d* state, Eigen::Matrix2d* covariance) const;
  double offsetAt(double stamp_s) const;
  double sigmaAt(double stamp_s) const;  // the reported 1-sigma of offsetAt (floor included), seconds
  double rate() const { return state_(1); }
  // The drift rate's 1-sigma (s/s): the filter's, with systematic_rate_sigma in quadrature.
  double rateSigma() const;
  // The learned scale of the windows' reported 1-sigma (>= 1).
  double noiseScale() const { return noise_scale_; }
  // The learned correlation of consecutive windows' errors (0 until learned).
  double windowCorrelation() const { return correlation_; }
  // The last innovation over its combined sigma (0 before the second window).
  double lastNormalisedInnovation() const { return last_normalised_innovation_; }
  const ClockModelOptions& options() const { return options_; }

 private:
  // The window's error variance as learned (its 1-sigma times the scale, squared).
  double windowVariance(const ClockMeasurement& measurement) const;

  ClockModelOptions options_;
  bool initialised_ = false;
  Eigen::Vector2d state_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_ = Eigen::Matrix2d::Zero();
  double stamp_s_ = 0.0;
  double noise_scale_ = 1.0;
  double mean_excess_ = 0.0;    // exponential mean of (innovation^2 - predicted variance) / sigma^2
  double mean_square_ = 0.0;    // ... of innovation^2 / sigma^2
  double mean_lag_ = 0.0;       // ... of the products of consecutive normalised innovations
  double last_normalised_ = 0.0;
  bool has_last_innovation_ = false;
  double correlation_ = 0.0;    // of consecutive windows' errors, learned
  double memory_weight_ = 0.0;  // of that mean (it starts with few windows)
  double last_normalised_innovation_ = 0.0;
};

}  // namespace deep_ois
