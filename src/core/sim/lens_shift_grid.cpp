#include "deep_ois/core/sim/lens_shift_grid.h"

#include <stdexcept>
#include <utility>

namespace deep_ois {
namespace sim {

LensShiftGrid::LensShiftGrid(double start_s, double rate_hz, std::vector<Eigen::Vector2d> samples)
    : start_s_(start_s), rate_hz_(rate_hz), samples_(std::move(samples)) {
  if (!(rate_hz > 0.0)) throw std::invalid_argument("LensShiftGrid: rate_hz must be positive");
}

double LensShiftGrid::endS() const {
  return samples_.empty() ? start_s_
                          : start_s_ + static_cast<double>(samples_.size() - 1) / rate_hz_;
}

Eigen::Vector2d LensShiftGrid::at(double t_s) const {
  if (samples_.empty()) return Eigen::Vector2d::Zero();
  const double position = (t_s - start_s_) * rate_hz_;
  const double last = static_cast<double>(samples_.size() - 1);
  if (!(position > 0.0)) return samples_.front();
  if (position >= last) return samples_.back();
  const std::size_t j = static_cast<std::size_t>(position);
  const double alpha = position - static_cast<double>(j);
  return (1.0 - alpha) * samples_[j] + alpha * samples_[j + 1];
}

}  // namespace sim
}  // namespace deep_ois
