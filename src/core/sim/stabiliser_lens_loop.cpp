#include "deep_ois/core/sim/stabiliser_lens_loop.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ois/lens_actuator.h"
#include "deep_ois/core/sim/stabiliser_controller.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;

// One axis of a PI position loop around a spring-mass lens: force F = kp e + ki integral(e), the
// lens x'' = wp^2 (F - x) - 2 zeta wp x', semi-implicit Euler at the control step (wp dt << 1).
// The lens stops dead at +-limit_px (its end stop); the integrator is held while it rests there
// (anti-windup).
class PiLensLoop {
 public:
  PiLensLoop(const OisConfig& config, double step_s, double limit_px)
      : wp_(2.0 * kPi * config.pi_plant_natural_hz),
        zeta_(config.pi_plant_damping),
        kp_(config.pi_kp),
        ki_(config.pi_ki),
        dt_(step_s),
        limit_px_(limit_px) {}

  // `command_px` minus the Hall reading's error, as the loop sees it; returns the lens position.
  double advance(double command_px) {
    const double error = command_px - position_px_;
    const bool at_stop = std::abs(position_px_) >= limit_px_ && error * position_px_ > 0.0;
    if (!at_stop) integral_ += error * dt_;
    const double force = kp_ * error + ki_ * integral_;
    velocity_ += dt_ * (wp_ * wp_ * (force - position_px_) - 2.0 * zeta_ * wp_ * velocity_);
    position_px_ += dt_ * velocity_;
    if (std::abs(position_px_) > limit_px_) {
      position_px_ = std::copysign(limit_px_, position_px_);
      if (velocity_ * position_px_ > 0.0) velocity_ = 0.0;
    }
    return position_px_;
  }

 private:
  double wp_, zeta_, kp_, ki_, dt_, limit_px_;
  double position_px_ = 0.0, velocity_ = 0.0, integral_ = 0.0;
};

}  // namespace

// Sign of the cancelling shift and the discretisation: see OisModel (core/sim/ois_model.cpp).
LensShiftGrid runStabiliser(const OisConfig& config, double focal_px, double start_s, int steps,
                            const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                            std::mt19937* noise) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("ois: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || steps < 1) {
    throw std::invalid_argument("runStabiliser: focal_px must be positive and steps at least 1");
  }
  const double dt = 1.0 / config.control_rate_hz;
  const double stroke_limit_px = focal_px * std::tan(config.stroke_limit_deg * kPi / 180.0);
  const double limit_y_deg =
      config.stroke_limit_y_deg > 0.0 ? config.stroke_limit_y_deg : config.stroke_limit_deg;
  const double stroke_limit_y_px = focal_px * std::tan(limit_y_deg * kPi / 180.0);
  std::vector<Eigen::Vector2d> shifts(static_cast<std::size_t>(steps) + 1, Eigen::Vector2d::Zero());
  // The stabiliser's gyro: turned by the mount's rotation about the optical axis, with its noise.
  const double mount = config.mount_rotation_deg * kPi / 180.0;
  const double mount_c = std::cos(mount), mount_s = std::sin(mount);
  auto measuredRate = [&](int j) {
    const Eigen::Vector3d w = angular_velocity_rad_s(start_s + j * dt);
    // Only pitch and tilt rates matter to the stabilizer; noise on both.
    const double noise_x = noise ? config.gyro_noise_rad_s * gaussian(*noise) : 0.0;
    const double noise_y = noise ? config.gyro_noise_rad_s * gaussian(*noise) : 0.0;
    if (mount == 0.0) return Eigen::Vector2d(w.x() + noise_x, w.y() + noise_y);
    return Eigen::Vector2d(mount_c * w.x() + mount_s * w.y() + noise_x,
                           -mount_s * w.x() + mount_c * w.y() + noise_y);
  };

  LensActuator actuator_x(config.actuator_natural_hz, config.actuator_damping, dt,
                          stroke_limit_px);
  LensActuator actuator_y(config.actuator_natural_hz, config.actuator_damping, dt,
                          stroke_limit_y_px);
  const bool pi_loop = config.position_loop == "pi";
  PiLensLoop pi_x(config, dt, stroke_limit_px), pi_y(config, dt, stroke_limit_y_px);
  StabiliserController controller(config, focal_px);
  // Commands waiting out the Hall sensor's delay and the digital loop's (the loop reacts to them
  // that much later).
  const int lag_steps = static_cast<int>(
      std::lround((config.hall_lag_s + config.digital_delay_s) * config.control_rate_hz));
  std::vector<Eigen::Vector2d> pending(static_cast<std::size_t>(lag_steps) + 1,
                                       Eigen::Vector2d::Zero());
  // A digital loop updates every `tick` control steps from the gyro sample of that step.
  const int tick = config.digital_rate_hz > 0.0
                       ? std::max(1, static_cast<int>(std::lround(config.control_rate_hz /
                                                                  config.digital_rate_hz)))
                       : 0;
  Eigen::Vector2d rate = measuredRate(0);
  Eigen::Vector2d command = controller.command();
  for (int j = 0; j < steps; ++j) {
    // The command of step j is held until the controller's next update (zero-order hold).
    if (tick == 0) command = controller.command();
    pending[static_cast<std::size_t>(j % (lag_steps + 1))] = command;
    // What the loop acts on: the command of lag_steps ago, against a noisy position reading (the
    // lens settles where the reading equals the command: off by the reading's noise).
    Eigen::Vector2d effective = pending[static_cast<std::size_t>((j + 1) % (lag_steps + 1))];
    if (noise && config.hall_noise_px > 0.0) {  // no draw otherwise: other configs keep theirs
      const double noise_x = gaussian(*noise);
      const double noise_y = gaussian(*noise);
      effective -= config.hall_noise_px * Eigen::Vector2d(noise_x, noise_y);
    }
    Eigen::Vector2d lens =
        pi_loop ? Eigen::Vector2d(pi_x.advance(effective.x()), pi_y.advance(effective.y()))
                : Eigen::Vector2d(actuator_x.advance(effective.x()), actuator_y.advance(effective.y()));
    if (config.actuator_cross_coupling != 0.0) {
      const double c = config.actuator_cross_coupling;
      lens = Eigen::Vector2d(lens.x() + c * lens.y(), lens.y() + c * lens.x());
    }
    shifts[static_cast<std::size_t>(j) + 1] = lens;
    const Eigen::Vector2d next_rate = measuredRate(j + 1);
    if (tick == 0) {
      controller.advance(0.5 * (rate + next_rate), next_rate, dt);
    } else if ((j + 1) % tick == 0) {
      // The digital controller sees only its own samples: the rate of this step, held over its
      // period (no anti-aliasing), then commands once.
      controller.advance(next_rate, next_rate, tick * dt);
      command = controller.command();
    }
    rate = next_rate;
  }
  return LensShiftGrid(start_s, config.control_rate_hz, std::move(shifts));
}

}  // namespace sim
}  // namespace deep_ois
