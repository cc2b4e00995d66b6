#include "deep_ois/core/sim/lens_log_model.h"

#include <Eigen/LU>
#include <cmath>
#include <random>
#include <stdexcept>

#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

std::string LensLogConfig::validate() const {
  if (!std::isfinite(rate_hz) || rate_hz <= 0.0 || rate_hz > 100000.0)
    return "rate_hz: must be in (0, 100000]";
  if (!std::isfinite(latency_s) || latency_s < 0.0 || latency_s > 5.0)
    return "latency_s: must be in [0, 5] s";
  if (!std::isfinite(noise_px) || noise_px < 0.0) return "noise_px: must be non-negative";
  if (!std::isfinite(quantisation) || quantisation < 0.0)
    return "quantisation: must be non-negative";
  if (!(dropout_probability >= 0.0 && dropout_probability < 1.0))
    return "dropout_probability: must be in [0, 1)";
  if (!std::isfinite(gap_rate_hz) || gap_rate_hz < 0.0) return "gap_rate_hz: must be non-negative";
  if (!std::isfinite(gap_duration_s) || gap_duration_s < 0.0)
    return "gap_duration_s: must be non-negative";
  const std::string problem = convention.validate();
  return problem.empty() ? "" : "convention: " + problem;
}

std::vector<LoggedLensSample> simulateLensLog(
    const LensLogConfig& config, const std::function<Eigen::Vector2d(double)>& true_shift_px,
    double t0_s, double t1_s, std::uint32_t seed) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("lens log: " + problem);
  // Separate streams: the noise of a sample does not depend on whether gaps are configured.
  std::mt19937 noise_rng = streamGenerator(seed, 0);
  std::mt19937 drop_rng = streamGenerator(seed, 1);
  std::mt19937 gap_rng = streamGenerator(seed, 2);

  // Outages as [start, end) intervals, Poisson in time.
  std::vector<std::pair<double, double>> gaps;
  if (config.gap_rate_hz > 0.0) {
    for (double t = t0_s;;) {
      t += -std::log(1.0 - uniform01(gap_rng)) / config.gap_rate_hz;
      if (t > t1_s) break;
      gaps.emplace_back(t, t + config.gap_duration_s);
    }
  }
  auto in_gap = [&gaps](double t) {
    for (const auto& [begin, end] : gaps) {
      if (t >= begin && t < end) return true;
    }
    return false;
  };

  const Eigen::Matrix2d to_logged = config.convention.matrix().inverse();
  // The noise in logged units: image-pixel noise through the inverse map.
  const double noise_logged = config.noise_px / config.convention.scale;
  const double variance =
      noise_logged * noise_logged + config.quantisation * config.quantisation / 12.0;
  std::vector<LoggedLensSample> log;
  const double dt = 1.0 / config.rate_hz;
  for (long k = 0;; ++k) {
    const double t = t0_s + k * dt;
    if (t > t1_s) break;
    const double noise_x = gaussian(noise_rng), noise_y = gaussian(noise_rng);
    const bool dropped = uniform01(drop_rng) < config.dropout_probability;
    if (dropped || in_gap(t)) continue;
    Eigen::Vector2d logged =
        to_logged * true_shift_px(t) + noise_logged * Eigen::Vector2d(noise_x, noise_y);
    if (config.quantisation > 0.0)
      logged = (logged / config.quantisation).array().round() * config.quantisation;
    LoggedLensSample out;
    out.sample.stamp_s = t - config.convention.time_offset_s;
    out.sample.logged = logged;
    out.sample.covariance = Eigen::Matrix2d::Identity() * variance;
    out.arrival_s = t + config.latency_s;
    log.push_back(out);
  }
  return log;
}

}  // namespace sim
}  // namespace deep_ois
