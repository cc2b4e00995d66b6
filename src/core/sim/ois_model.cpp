#include "deep_ois/core/sim/ois_model.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
// The actuator's resonance must be well resolved by the control loop.
constexpr double kMinControlStepsPerActuatorPeriod = 4.0;

// exp(M) of a 3x3 matrix by scaling and squaring with a Taylor series (to double precision).
Eigen::Matrix3d expm(const Eigen::Matrix3d& M) {
  const double norm = M.cwiseAbs().rowwise().sum().maxCoeff();
  int squarings = 0;
  while (norm / std::ldexp(1.0, squarings) > 0.5) ++squarings;
  const Eigen::Matrix3d A = M / std::ldexp(1.0, squarings);
  Eigen::Matrix3d result = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d term = Eigen::Matrix3d::Identity();
  for (int n = 1; n <= 18; ++n) {
    term = term * A / n;
    result += term;
  }
  for (int i = 0; i < squarings; ++i) result = result * result;
  return result;
}

}  // namespace

std::string OisConfig::validate() const {
  std::ostringstream why;
  auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
  if (!std::isfinite(highpass_corner_hz) || highpass_corner_hz < 0.0) {
    why << "highpass_corner_hz: must be non-negative, 0 = no centring (got " << highpass_corner_hz
        << " Hz)";
  } else if (!positive(actuator_natural_hz)) {
    why << "actuator_natural_hz: must be positive (got " << actuator_natural_hz << " Hz)";
  } else if (!positive(actuator_damping)) {
    why << "actuator_damping: must be positive (got " << actuator_damping << ")";
  } else if (!(stroke_limit_deg > 0.0 && stroke_limit_deg < 45.0)) {
    why << "stroke_limit_deg: must be in (0, 45) degrees (got " << stroke_limit_deg << ")";
  } else if (!(gain >= 0.0 && gain <= 2.0)) {
    why << "gain: must be in [0, 2] (got " << gain << ")";
  } else if (!std::isfinite(gyro_noise_rad_s) || gyro_noise_rad_s < 0.0) {
    why << "gyro_noise_rad_s: must be non-negative (got " << gyro_noise_rad_s << ")";
  } else if (!positive(control_rate_hz) ||
             control_rate_hz < kMinControlStepsPerActuatorPeriod * actuator_natural_hz) {
    why << "control_rate_hz: must be at least " << kMinControlStepsPerActuatorPeriod
        << " x actuator_natural_hz (got " << control_rate_hz << " Hz)";
  }
  return why.str();
}

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
  const Eigen::Matrix3d e = expm(augmented);
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

// Sign of the cancelling shift, in the optical frame (x right, y down, z forward) and with
// rotationHomography(K, R_b_a) = K R_b_a K^-1, R_b_a = R_b^T R_a (camera a -> camera b):
//  - the camera turns by +theta about its own y axis: R_b = R_a exp(theta [e_y]x), so
//    R_b_a = Ry(-theta) and the centre ray (0, 0, 1) of frame a becomes (-sin, 0, cos) in frame
//    b: the image centre moves by -f tan(theta) in x; the lens must add +f tan(theta_y) in x;
//  - about +x: R_b_a = Rx(-theta) maps (0, 0, 1) to (0, sin, cos): the centre moves by
//    +f tan(theta) in y; the lens must add -f tan(theta_x) in y.
// Hence s_cmd = gain * f * (tan(theta_y), -tan(theta_x)) for a shift that moves image points by
// +s. For a rotation about one axis this cancels the image motion of the direction that was at
// the centre when the (high-passed) angle was zero exactly; test_ois_model checks it against
// rotationHomography. Roll (about z) moves the centre nowhere and is not integrated.
//
// The stabilizer integrates each axis' rate on its own (as real OIS controllers do): for the
// small angles of a shake the difference to composing rotations is second order. The centring
// high-pass on the integrated angle, theta_hp = s / (s + wc) * theta with theta' = w, is the
// leaky integrator theta_hp' = w - wc theta_hp, discretised exactly for the mean rate of a step.
OisModel::OisModel(const OisConfig& config, const CameraMotion& motion, double focal_px,
                   std::uint32_t seed)
    : config_(config), start_s_(motion.startTime()) {
  const std::string problem = config_.validate();
  if (!problem.empty()) throw std::invalid_argument("ois: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px)) {
    std::ostringstream why;
    why << "ois: focal_px must be positive (got " << focal_px << ")";
    throw std::invalid_argument(why.str());
  }
  stroke_limit_px_ = focal_px * std::tan(config_.stroke_limit_deg * kPi / 180.0);
  if (!config_.enabled) return;

  const double dt = 1.0 / config_.control_rate_hz;
  const int steps = std::max(
      1, static_cast<int>(std::ceil((motion.endTime() - start_s_) * config_.control_rate_hz)));
  const double wc = 2.0 * kPi * config_.highpass_corner_hz;
  const double decay = std::exp(-wc * dt);
  const double rate_weight = wc > 0.0 ? -std::expm1(-wc * dt) / wc : dt;

  std::mt19937 rng(seed);
  auto measuredRate = [&](int j) {
    const Eigen::Vector3d w = motion.angularVelocity(start_s_ + j * dt);
    // Only pitch and tilt rates matter to the stabilizer; noise on both.
    const double noise_x = config_.gyro_noise_rad_s * gaussian(rng);
    const double noise_y = config_.gyro_noise_rad_s * gaussian(rng);
    return Eigen::Vector2d(w.x() + noise_x, w.y() + noise_y);
  };

  LensActuator actuator_x(config_.actuator_natural_hz, config_.actuator_damping, dt,
                          stroke_limit_px_);
  LensActuator actuator_y(config_.actuator_natural_hz, config_.actuator_damping, dt,
                          stroke_limit_px_);
  const double scale_px = config_.gain * focal_px;
  shift_grid_.assign(steps + 1, Eigen::Vector2d::Zero());
  Eigen::Vector2d theta = Eigen::Vector2d::Zero();  // high-passed (x, y) angles, rad
  Eigen::Vector2d rate = measuredRate(0);
  for (int j = 0; j < steps; ++j) {
    // The command of step j is held until the controller's next update (zero-order hold).
    const double command_x =
        std::clamp(scale_px * std::tan(theta.y()), -stroke_limit_px_, stroke_limit_px_);
    const double command_y =
        std::clamp(-scale_px * std::tan(theta.x()), -stroke_limit_px_, stroke_limit_px_);
    shift_grid_[j + 1] =
        Eigen::Vector2d(actuator_x.advance(command_x), actuator_y.advance(command_y));
    const Eigen::Vector2d next_rate = measuredRate(j + 1);
    theta = decay * theta + rate_weight * 0.5 * (rate + next_rate);
    rate = next_rate;
  }
}

Eigen::Vector2d OisModel::lensShift(double t_s) const {
  if (shift_grid_.empty()) return Eigen::Vector2d::Zero();
  const double position = (t_s - start_s_) * config_.control_rate_hz;
  const double last = static_cast<double>(shift_grid_.size() - 1);
  if (!(position > 0.0)) return shift_grid_.front();
  if (position >= last) return shift_grid_.back();
  const std::size_t j = static_cast<std::size_t>(position);
  const double alpha = position - static_cast<double>(j);
  return (1.0 - alpha) * shift_grid_[j] + alpha * shift_grid_[j + 1];
}

}  // namespace sim
}  // namespace deep_ois
