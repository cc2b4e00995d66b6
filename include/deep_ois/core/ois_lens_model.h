// A generic model of what an optical image stabiliser does with its lens, for estimators that
// have to live with it (the camera-IMU calibration). Pure Eigen: no ROS.
//
// Every OIS controller integrates its own gyro's pan and tilt rates into an angle, pulls that
// angle back towards the centre (otherwise a pan would park the lens at its end stop), shifts the
// lens against it by about focal x angle, within its stroke, through an actuator that lags. The
// model keeps exactly that and nothing simulator-specific: per axis
//     theta' = omega - 2 pi corner theta                       (leaky integrator, centring)
//     s(t)   = centre + clamp(gain * theta(t - delay), +-stroke)
// with the x shift driven by the pan (rate about the camera y axis) and the y shift by the tilt
// (about x); never by roll, which a lens shift cannot undo. The actuator's lag is a pure delay
// (a second-order actuator well above the shake band delays it by about 2 damping / natural
// frequency, nearly the same at every frequency of hand shake). Seven parameters, fitted to a
// recording by fitOisLensModel(); a stabiliser that behaves otherwise shows as a large fit
// residual, which the caller turns into a weak prior.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace deep_ois {

struct OisLensModel {
  // Shift per radian of (pan, tilt): x from the angle about the camera y axis, y from the angle
  // about x. Signed: an OIS cancels image motion, which sets the signs, but the fit finds them.
  Eigen::Vector2d gain_px_per_rad = Eigen::Vector2d::Zero();
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // rest position of the lens
  double centring_corner_hz = 0.6;  // the leaky integrator's corner
  double delay_s = 0.005;           // actuator lag
  double stroke_px = 1e9;           // |shift - centre| per axis at most this
};

// Camera-frame rates (rad/s, optical frame: x right, y down, z forward) sampled every step_s from
// a start time, and the lens shift the model predicts at those same times (pixels). The
// integrator starts at rest at the first sample.
std::vector<Eigen::Vector2d> predictOisLensShift(const OisLensModel& model,
                                                 const std::vector<Eigen::Vector3d>& camera_rates_rad_s,
                                                 double step_s);

// The prediction at a fractional sample index (linear interpolation, clamped to the ends).
Eigen::Vector2d interpolateLensShift(const std::vector<Eigen::Vector2d>& shifts_px, double index);

struct OisLensSample {
  double index = 0.0;  // fractional sample index into the rates of the fit
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();
};

struct OisLensFit {
  OisLensModel model;
  double rms_residual_px = 0.0;  // of the samples about the fitted model
  double rms_shift_px = 0.0;     // of the samples about their mean (what there was to explain)
};

// Least-squares fit of the model to lens-shift samples (e.g. the per-frame shifts a calibration
// estimated freely), given the camera rates that drove them: a linear fit of gain and centre
// over a few corners, then Levenberg-Marquardt over all seven parameters. Throws
// std::invalid_argument for fewer than 10 samples or a non-positive step.
OisLensFit fitOisLensModel(const std::vector<Eigen::Vector3d>& camera_rates_rad_s, double step_s,
                           const std::vector<OisLensSample>& samples);

}  // namespace deep_ois
