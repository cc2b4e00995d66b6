#include "deep_ois/core/sim/lens_shift_grid.h"

#include <stdexcept>
#include <utility>

#include "deep_ois/core/common/uniform_grid_interpolation.h"

namespace deep_ois {
namespace sim {

LensShiftGrid::LensShiftGrid(double start_s, double rate_hz, std::vector<Eigen::Vector2d> samples)
    : start_s_(start_s), rate_hz_(rate_hz), samples_(std::move(samples)) {
  if (!(rate_hz > 0.0)) throw std::invalid_argument("LensShiftGrid: rate_hz must be positive");
}

Eigen::Vector2d LensShiftGrid::at(double t_s) const {
  if (samples_.empty()) return Eigen::Vector2d::Zero();
  return interpolateOnUniformGrid(samples_, (t_s - start_s_) * rate_hz_);
}

}  // namespace sim
}  // namespace deep_ois
