#include "deep_ois/core/ois/lens_actuator.h"

#include <cmath>
#include <stdexcept>

#include "deep_ois/core/common/matrix_exponential.h"

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;

}  // namespace

// With y = x' / wn the system is d(x, y)/dt = wn [[0, 1], [-1, -2 zeta]] (x, y) + wn (0, 1) u.
// For u held over a step h, (x, y)(h) = Phi (x, y)(0) + Gamma u, read off the matrix exponential
// of the augmented [[A h, B h], [0, 0]]. Exact for any step, hence stable for any step.
LensActuator::LensActuator(double natural_hz, double damping, double step_s, double limit_px)
    : natural_rad_s_(2.0 * kPi * natural_hz), limit_px_(limit_px) {
  if (!(natural_hz > 0.0) || !(damping > 0.0) || !(step_s > 0.0) || !(limit_px >= 0.0) ||
      !std::isfinite(natural_hz * damping * step_s)) {
    throw std::invalid_argument(
        "lens actuator: natural_hz, damping and step_s must be positive and limit_px >= 0");
  }
  const double wh = natural_rad_s_ * step_s;
  Eigen::Matrix3d augmented;
  augmented << 0.0, wh, 0.0,         //
      -wh, -2.0 * damping * wh, wh,  //
      0.0, 0.0, 0.0;
  const Eigen::Matrix3d e = matrixExponential(augmented);
  transition_ = e.topLeftCorner<2, 2>();
  input_ = e.topRightCorner<2, 1>();
}

double LensActuator::advance(double command_px) {
  const Eigen::Vector2d state =
      transition_ * Eigen::Vector2d(position_px_, velocity_scaled_) + input_ * command_px;
  position_px_ = state.x();
  velocity_scaled_ = state.y();
  // End stop: an inelastic stop, the lens rests against it until pulled back.
  if (std::abs(position_px_) > limit_px_) {
    position_px_ = std::copysign(limit_px_, position_px_);
    if (velocity_scaled_ * position_px_ > 0.0) velocity_scaled_ = 0.0;
  }
  return position_px_;
}

}  // namespace deep_ois
