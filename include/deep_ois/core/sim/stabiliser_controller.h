// The simulator stabiliser's controller: from its own gyro's pan/tilt rate to the commanded lens
// shift (pixels), before the lens position loop (core/sim/ois_model.h runs the loop, the digital
// timing and the mount around it).
//
// Why a family of controllers: real phones do not all high-pass an integrated angle. The
// simulator offers the designs they use, so the learned stabiliser model is measured on more than
// one structure:
//  - "highpass": integrate, re-centre with a first-order corner (optionally faster during a
//    detected pan, optionally faster the further the lens is out: excursion-dependent
//    re-centring);
//  - "kalman": an intended-motion estimator. The integrated angle is the intended camera path
//    (a constant-velocity model driven by white acceleration) plus the shake (measurement noise);
//    a Kalman filter estimates the intended path and the lens cancels the rest. A manoeuvre gate
//    inflates the process noise when the innovation is implausible, so a deliberate pan is
//    followed quickly (the lens lets go).
// Either may end in a hard stroke (clip) or a soft one (f tanh(command / stroke)), and the command
// may be quantised (a DAC's least significant bit).
#pragma once

#include <Eigen/Core>
#include <string>

namespace deep_ois {
namespace sim {

struct OisConfig;

class StabiliserController {
 public:
  // `config` must be valid (OisConfig::validate()); `focal_px` sets pixels per radian.
  StabiliserController(const OisConfig& config, double focal_px);

  // The command for the current state (pixels, x right, y down), stroke and quantisation applied.
  Eigen::Vector2d command() const;
  // Advances the state by `step_s` with the stabiliser-gyro pan/tilt rate (camera x, y): its mean
  // over the step (integrated) and its newest sample (what the pan detector low-passes).
  void advance(const Eigen::Vector2d& mean_rate_rad_s, const Eigen::Vector2d& newest_rate_rad_s,
               double step_s);

  // The angle the lens is asked to cancel (rad, x and y), before gain, stroke and quantisation.
  const Eigen::Vector2d& cancelledAngle() const { return theta_; }

 private:
  Eigen::Vector2d rawCommand() const;
  void advanceHighpass(const Eigen::Vector2d& rate, const Eigen::Vector2d& newest, double step_s);
  void advanceKalman(const Eigen::Vector2d& rate, double step_s);

  const OisConfig& config_;
  double focal_px_;
  Eigen::Vector2d stroke_px_;
  // High-pass state: the cancelled angle; pan detector.
  Eigen::Vector2d theta_ = Eigen::Vector2d::Zero();
  double smoothed_rate_ = 0.0;
  bool panning_ = false;
  // Kalman state per axis: integrated angle, intended angle and rate, covariance (2 x 2).
  Eigen::Vector2d integrated_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d intended_ = Eigen::Matrix2d::Zero();  // column a: (angle, rate) of axis a
  Eigen::Matrix2d covariance_[2];
};

}  // namespace sim
}  // namespace deep_ois
