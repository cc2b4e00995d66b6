// The lens actuator of an optical image stabiliser: one axis of a voice-coil lens under its
// position loop. Shared by the simulator's stabiliser (core/sim/ois_model.h) and the learned
// stabiliser model (core/ois/stabiliser_model.h), so both integrate the same physics.
#pragma once

#include <Eigen/Core>

namespace deep_ois {

// The lens actuator of one axis (voice coil with its position loop), a second-order system from
// the commanded to the actual shift: x'' = wn^2 (x_cmd - x) - 2 zeta wn x', discretised exactly
// for a command held over each step. The lens stops dead at +-limit_px (its end stop).
class LensActuator {
 public:
  // Throws std::invalid_argument unless natural_hz, damping and step_s are positive and
  // limit_px is non-negative.
  LensActuator(double natural_hz, double damping, double step_s, double limit_px);

  // Holds `command_px` for one step and returns the position at the end of it, pixels.
  double advance(double command_px);
  double positionPx() const { return position_px_; }
  double velocityPxPerS() const { return velocity_scaled_ * natural_rad_s_; }

 private:
  double natural_rad_s_;
  double limit_px_;
  // State (x, x' / wn): both in pixels, so the transition matrix is well conditioned.
  Eigen::Matrix2d transition_;
  Eigen::Vector2d input_;
  double position_px_ = 0.0;
  double velocity_scaled_ = 0.0;
};

}  // namespace deep_ois
