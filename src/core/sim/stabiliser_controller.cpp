#include "deep_ois/core/sim/stabiliser_controller.h"

#include <algorithm>
#include <cmath>

#include "deep_ois/core/ois/intended_motion_tracker.h"
#include "deep_ois/core/sim/ois_model.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The leaky integrator y' = w - c y over one step for the step's mean rate w: exact.
double leakDecay(double corner_rad_s, double h) { return std::exp(-corner_rad_s * h); }
double leakWeight(double corner_rad_s, double h) {
  return corner_rad_s > 0.0 ? -std::expm1(-corner_rad_s * h) / corner_rad_s : h;
}

}  // namespace

StabiliserController::StabiliserController(const OisConfig& config, double focal_px)
    : config_(config), focal_px_(focal_px) {
  const double limit_y_deg =
      config.stroke_limit_y_deg > 0.0 ? config.stroke_limit_y_deg : config.stroke_limit_deg;
  stroke_px_ = Eigen::Vector2d(focal_px * std::tan(config.stroke_limit_deg * kPi / 180.0),
                               focal_px * std::tan(limit_y_deg * kPi / 180.0));
  // The filter starts confident that the camera is still (a small covariance): it has been on.
  for (Eigen::Matrix2d& p : covariance_) p = 1e-8 * Eigen::Matrix2d::Identity();
}

Eigen::Vector2d StabiliserController::rawCommand() const {
  // s = gain f (tan theta_y, -tan theta_x): see OisModel's sign derivation.
  const double scale_px = config_.gain * focal_px_;
  return Eigen::Vector2d(scale_px * std::tan(theta_.y()), -scale_px * std::tan(theta_.x()));
}

Eigen::Vector2d StabiliserController::command() const {
  Eigen::Vector2d c = rawCommand();
  const bool circle = config_.stroke_shape == StrokeShape::kCircle;
  if (config_.soft_stroke) {
    // A soft end: the command approaches the stroke smoothly (f tanh(c / f) per axis or radially).
    if (circle) {
      const double r = std::hypot(c.x() / stroke_px_.x(), c.y() / stroke_px_.y());
      if (r > 1e-12) c *= std::tanh(r) / r;
    } else {
      c = Eigen::Vector2d(stroke_px_.x() * std::tanh(c.x() / stroke_px_.x()),
                          stroke_px_.y() * std::tanh(c.y() / stroke_px_.y()));
    }
  } else if (circle) {
    const double r = std::hypot(c.x() / stroke_px_.x(), c.y() / stroke_px_.y());
    if (r > 1.0) c /= r;
  } else {
    c = Eigen::Vector2d(std::clamp(c.x(), -stroke_px_.x(), stroke_px_.x()),
                        std::clamp(c.y(), -stroke_px_.y(), stroke_px_.y()));
  }
  if (config_.command_lsb_deg > 0.0) {
    const double lsb_px = focal_px_ * std::tan(config_.command_lsb_deg * kPi / 180.0);
    c = Eigen::Vector2d(lsb_px * std::round(c.x() / lsb_px), lsb_px * std::round(c.y() / lsb_px));
  }
  return c;
}

void StabiliserController::advance(const Eigen::Vector2d& mean_rate_rad_s,
                                   const Eigen::Vector2d& newest_rate_rad_s, double step_s) {
  if (config_.controller == "kalman") {
    advanceKalman(mean_rate_rad_s, step_s);
  } else {
    advanceHighpass(mean_rate_rad_s, newest_rate_rad_s, step_s);
  }
}

void StabiliserController::advanceHighpass(const Eigen::Vector2d& rate,
                                           const Eigen::Vector2d& newest, double step_s) {
  if (config_.pan_detection_rate_rad_s > 0.0) {
    const double smoothing = -std::expm1(-step_s / config_.pan_detection_time_constant_s);
    smoothed_rate_ += smoothing * (newest.norm() - smoothed_rate_);
    if (!panning_ && smoothed_rate_ > config_.pan_detection_rate_rad_s) panning_ = true;
    if (panning_ && smoothed_rate_ < 0.7 * config_.pan_detection_rate_rad_s) panning_ = false;
  }
  const double base_corner =
      2.0 * kPi * (panning_ ? config_.pan_release_corner_hz : config_.highpass_corner_hz);
  if (config_.excursion_recentring_gain <= 0.0) {
    theta_ = leakDecay(base_corner, step_s) * theta_ + leakWeight(base_corner, step_s) * rate;
    return;
  }
  // Excursion-dependent re-centring: the corner grows with the lens' excursion relative to its
  // stroke (per axis), so the lens is pulled back hard before it reaches the end.
  const double stroke_rad[2] = {std::atan(stroke_px_.y() / focal_px_),
                                std::atan(stroke_px_.x() / focal_px_)};  // theta_x drives y
  for (int a = 0; a < 2; ++a) {
    const double excursion = std::abs(config_.gain * theta_(a)) / stroke_rad[a];
    const double corner =
        base_corner * (1.0 + config_.excursion_recentring_gain *
                                 std::pow(excursion, config_.excursion_recentring_power));
    theta_(a) = leakDecay(corner, step_s) * theta_(a) + leakWeight(corner, step_s) * rate(a);
  }
}

void StabiliserController::advanceKalman(const Eigen::Vector2d& rate, double step_s) {
  // The intended path per axis (intended_motion_tracker.h); a pan beyond kalman_manoeuvre_deg lets
  // the estimate accelerate more.
  IntendedMotionTrackerStep step;
  step.step_s = step_s;
  step.bandwidth_hz = config_.kalman_bandwidth_hz;
  step.manoeuvre_rad = config_.kalman_manoeuvre_deg > 0.0 ? config_.kalman_manoeuvre_deg * kPi / 180.0 : 0.0;
  step.manoeuvre_factor = config_.kalman_manoeuvre_factor;
  integrated_ += step_s * rate;
  for (int a = 0; a < 2; ++a) {
    Eigen::Vector2d intended = intended_.col(a);
    advanceIntendedMotion(step, integrated_(a), intended, covariance_[a]);
    intended_.col(a) = intended;
    theta_(a) = integrated_(a) - intended(0);
  }
}

}  // namespace sim
}  // namespace deep_ois
