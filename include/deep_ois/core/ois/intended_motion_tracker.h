#pragma once

#include <Eigen/Core>

namespace deep_ois {

// The intended-motion estimator of a Kalman stabiliser, one axis: a constant-velocity path
// (angle [rad], rate [rad/s]) under white acceleration of spectral density q, the shake as
// measurement noise of density r = q / wn^4, which makes the steady filter a second-order tracker
// of bandwidth wn (a critically damped-like second-order high-pass for the lens). Shared by the
// simulator's Kalman module and the intended_motion stage's Kalman estimator.
struct IntendedMotionTrackerStep {
  double step_s = 0.0;
  double bandwidth_hz = 1.0;
  // Scales q (a bandwidth multiplier m gives m^4: the tracker m times faster).
  double process_noise_scale = 1.0;
  // A manoeuvre (an innovation above this angle [rad], 0: never) inflates the prediction's
  // covariance by (manoeuvre_factor - 1) Q, so the estimate catches up with a deliberate pan.
  double manoeuvre_rad = 0.0;
  double manoeuvre_factor = 1.0;
};

// Predicts the intended path one step ahead and corrects it with the integrated angle [rad]
// measured at the new time. `intended` = (angle, rate); `covariance` is kept symmetric.
void advanceIntendedMotion(const IntendedMotionTrackerStep& step, double integrated_angle_rad,
                           Eigen::Vector2d& intended, Eigen::Matrix2d& covariance);

}  // namespace deep_ois
