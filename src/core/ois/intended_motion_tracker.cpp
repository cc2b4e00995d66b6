#include "deep_ois/core/ois/intended_motion_tracker.h"

#include <cmath>

namespace deep_ois {

void advanceIntendedMotion(const IntendedMotionTrackerStep& step, double integrated_angle_rad,
                           Eigen::Vector2d& intended, Eigen::Matrix2d& covariance) {
  constexpr double kPi = 3.14159265358979323846;
  const double wn = 2.0 * kPi * step.bandwidth_hz;
  const double h = step.step_s;
  const double measurement_var = 1.0 / std::pow(wn, 4) / h;
  Eigen::Matrix2d F;
  F << 1.0, h, 0.0, 1.0;
  Eigen::Matrix2d Q;
  Q << h * h * h / 3.0, h * h / 2.0, h * h / 2.0, h;
  Q *= step.process_noise_scale;
  Eigen::Vector2d x = F * intended;
  Eigen::Matrix2d P = F * covariance * F.transpose() + Q;
  const double innovation = integrated_angle_rad - x(0);
  double S = P(0, 0) + measurement_var;
  if (step.manoeuvre_rad > 0.0 && std::abs(innovation) > step.manoeuvre_rad) {
    P += (step.manoeuvre_factor - 1.0) * Q;
    S = P(0, 0) + measurement_var;
  }
  const Eigen::Vector2d K = P.col(0) / S;
  x += K * innovation;
  P -= K * P.row(0);
  intended = x;
  covariance = 0.5 * (P + P.transpose());
}

}  // namespace deep_ois
