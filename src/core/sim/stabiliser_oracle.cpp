#include "deep_ois/core/sim/stabiliser_oracle.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "deep_ois/core/ois/camera_rate_cursor.h"
#include "deep_ois/core/sim/stabiliser_lens_loop.h"

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
  const int steps = std::max(
      1, static_cast<int>(std::ceil((last_s_ - start_s_) * config.control_rate_hz)));
  // The controller asks for the rate at its steps in increasing time.
  CameraRateCursor rate(samples);
  grid_ = runStabiliser(config, focal_px, start_s_, steps,
                        [&rate](double t_s) { return rate.at(t_s); }, nullptr);
}

}  // namespace sim
}  // namespace deep_ois
