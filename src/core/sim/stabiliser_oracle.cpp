#include "deep_ois/core/sim/stabiliser_oracle.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "deep_ois/core/ois/camera_rate_cursor.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"

namespace deep_ois {
namespace sim {

StabiliserOracle::StabiliserOracle(const OisConfig& config, double focal_px,
                                   const std::vector<CameraRateSample>& rates, double start_s) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser oracle: ois: " + problem);
  if (!config.enabled || !config.lens_shift_csv.empty()) {
    throw std::invalid_argument(
        "stabiliser oracle: the design has no stabiliser to run (ois.enabled false or "
        "ois.lens_shift_csv set)");
  }
  if (config.design_seed >= 0) {
    *this = StabiliserOracle(generateDesign(static_cast<std::uint32_t>(config.design_seed)),
                             focal_px, rates, start_s);
    return;
  }
  runOver(rates, start_s, config.control_rate_hz,
          [&](double start, int steps, const std::function<Eigen::Vector3d(double)>& rate) {
            return runStabiliser(config, focal_px, start, steps, rate, nullptr);
          });
}

StabiliserOracle::StabiliserOracle(const StabiliserDesign& design, double focal_px,
                                   const std::vector<CameraRateSample>& rates, double start_s) {
  const std::string problem = design.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser oracle: design: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px)) {
    throw std::invalid_argument("stabiliser oracle: focal_px must be positive");
  }
  runOver(rates, start_s, kDesignPhysicsRateHz,
          [&](double start, int steps, const std::function<Eigen::Vector3d(double)>& rate) {
            return runDesign(design, focal_px, start, steps, rate, nullptr);
          });
}

void StabiliserOracle::runOver(const std::vector<CameraRateSample>& rates, double start_s,
                               double rate_hz, const Runner& run) {
  std::vector<CameraRateSample> samples;
  samples.reserve(rates.size());
  for (const CameraRateSample& sample : rates) {
    if (!samples.empty() && !(sample.stamp_s > samples.back().stamp_s)) {
      ++dropped_;
      continue;
    }
    samples.push_back(sample);
  }
  if (samples.size() < 2) {
    throw std::invalid_argument("stabiliser oracle: fewer than two gyro samples in time order");
  }
  start_s_ = std::isnan(start_s) ? samples.front().stamp_s : start_s;
  last_s_ = samples.back().stamp_s;
  if (!std::isfinite(start_s_) || !(start_s_ < last_s_)) {
    throw std::invalid_argument("stabiliser oracle: the start must be finite and before the last "
                                "gyro sample");
  }
  const int steps = std::max(1, static_cast<int>(std::ceil((last_s_ - start_s_) * rate_hz)));
  // The controller asks for the rate at its steps in increasing time.
  CameraRateCursor rate(samples);
  grid_ = run(start_s_, steps, [&rate](double t_s) { return rate.at(t_s); });
}

}  // namespace sim
}  // namespace deep_ois
