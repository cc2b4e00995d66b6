// Optical image stabilizer: a lens shift, in pixels, driven by the stabilizer's own gyro.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_actuator.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/lens_shift_grid.h"

namespace deep_ois {
namespace sim {

// How far the lens may travel: per axis (a box) or inside an ellipse with those half-axes.
enum class StrokeShape { kBox, kCircle };

struct OisConfig {
  bool enabled = true;
  // Pan and tilt only: the stabilizer integrates the rates about camera x and y (never roll).
  // High-pass (centring) corner on the integrated angle, so the lens drifts back to centre.
  double highpass_corner_hz = 0.6;
  // Second-order actuator (voice coil) from commanded to actual shift.
  double actuator_natural_hz = 35.0;
  double actuator_damping = 0.7;
  double stroke_limit_deg = 1.0;  // commanded shift is clamped to f * tan(limit) pixels (x)
  double stroke_limit_y_deg = 0.0;  // the y axis' limit; 0 = the same as x (asymmetric if not)
  StrokeShape stroke_shape = StrokeShape::kBox;
  double gain = 1.0;  // fraction of the rotation the stabilizer cancels (< 1 under-, > 1 over-)
  double gyro_noise_rad_s = 0.002;  // white noise of the stabilizer's own gyro (per sample)
  double control_rate_hz = 4000.0;  // controller and actuator simulation rate
  // Pan detection (0 = off): while the low-passed pan/tilt rate magnitude exceeds this, the
  // stabiliser treats the motion as a deliberate pan and re-centres with pan_release_corner_hz
  // instead of highpass_corner_hz (it lets go); below 0.7 x the threshold it stabilises again.
  double pan_detection_rate_rad_s = 0.0;
  double pan_detection_time_constant_s = 0.1;  // low-pass of the rate it decides on
  double pan_release_corner_hz = 5.0;
  // Hall position sensor of the lens loop: white noise (pixels, per control step) and delay
  // (seconds). The loop drives the measured position to the command, so the lens itself sits
  // off by the noise and follows the command late by the delay.
  double hall_noise_px = 0.0;
  double hall_lag_s = 0.0;
  // The lens position loop: "second_order" (the actuator above: a voice coil whose loop behaves as
  // one second-order system) or "pi": a spring-mass lens (pi_plant_natural_hz, pi_plant_damping,
  // force in pixels of static deflection) under a PI controller on the Hall reading (pi_kp, pi_ki
  // in 1/s): zero steady-state error, a third-order closed loop that rings more, as many modules.
  std::string position_loop = "second_order";
  double pi_plant_natural_hz = 20.0;
  double pi_plant_damping = 0.7;
  double pi_kp = 4.0;
  double pi_ki = 300.0;
  // The controller (the intended_motion stage, core/sim/stabiliser_design_runner.h): "highpass"
  // (integrate and re-centre, the keys above) or "kalman" (an intended-motion estimator: a
  // constant-velocity Kalman filter on the integrated angle with this bandwidth; the lens cancels
  // the angle minus the intended path).
  std::string controller = "highpass";
  double kalman_bandwidth_hz = 0.5;
  // Manoeuvre gate (0 = off): while the innovation (integrated angle minus the predicted intended
  // angle) exceeds this angle, the process noise is multiplied by kalman_manoeuvre_factor (a pan
  // is followed quickly).
  double kalman_manoeuvre_deg = 0.0;
  double kalman_manoeuvre_factor = 100.0;
  // Excursion-dependent re-centring (highpass; 0 = off): the corner is multiplied by
  // 1 + gain * (|raw command| / stroke)^power per axis (the command before the stroke, in pixels).
  double excursion_recentring_gain = 0.0;
  double excursion_recentring_power = 2.0;
  // A soft stroke: the command is stroke * tanh(command / stroke) instead of clipped.
  bool soft_stroke = false;
  // A digital loop (0 = the controller runs every control step): the controller samples its gyro
  // and updates its command at digital_rate_hz (held in between), the command reaches the lens
  // digital_delay_s later and is quantised to command_lsb_deg (0 = not quantised).
  double digital_rate_hz = 0.0;
  double digital_delay_s = 0.0;
  double command_lsb_deg = 0.0;
  // The mount: the stabiliser's gyro turned by mount_rotation_deg about the optical axis against
  // the image, and the lens axes cross-coupled (image shift = [[1 c] [c 1]] x actuator shift).
  double mount_rotation_deg = 0.0;
  double actuator_cross_coupling = 0.0;
  // When not empty: the lens follows this trajectory instead of the stabiliser (a CSV with a
  // header line and rows "t_s,x_px,y_px", t in seconds from the start of the motion, e.g. a real
  // phone's lens log re-timed), linear between rows and held outside them.
  std::string lens_shift_csv;
  // When not -1: the lens is run by the generated stabiliser design of this seed
  // (core/sim/design_generator.h, 0..4294967295) instead of the stabiliser keys above, which are
  // then not used; `enabled` still turns it off (the non-OIS twin). Not with lens_shift_csv.
  std::int64_t design_seed = -1;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

const char* toString(StrokeShape shape);
// "box" or "circle"; false for anything else.
bool parseStrokeShape(const std::string& text, StrokeShape* shape);

// The lens actuator is shared with the learned stabiliser model (core/ois/lens_actuator.h).
using deep_ois::LensActuator;


// The principal-point shift the lens causes over [motion.startTime(), motion.endTime()].
// A shift s moves every image point by +s: the OIS camera's intrinsics at time t are K with
// (cx, cy) + lensShift(t). The stabilizer commands the shift that cancels the image motion of the
// high-passed pan/tilt angle (to first order: s = f * (theta_y, -theta_x)).
class OisModel {
 public:
  // Throws std::runtime_error naming the file and line when lens_shift_csv cannot be read.
  // focal_px: camera focal length in pixels (sets the px per rad and the stroke in px). Throws
  // std::invalid_argument with the validate() sentence. Keeps no reference to `motion`.
  OisModel(const OisConfig& config, const CameraMotion& motion, double focal_px, std::uint32_t seed);

  // Pixels (x right, y down), linear between control steps, held outside the span; zero when
  // disabled.
  Eigen::Vector2d lensShift(double t_s) const;
  bool enabled() const { return config_.enabled; }
  double strokeLimitPx() const { return stroke_limit_px_; }
  double strokeLimitYPx() const { return stroke_limit_y_px_; }

 private:
  OisConfig config_;
  double start_s_ = 0.0;
  double stroke_limit_px_ = 0.0;
  double stroke_limit_y_px_ = 0.0;
  LensShiftGrid grid_;  // at control_rate_hz from start_s_; empty when disabled
};

}  // namespace sim
}  // namespace deep_ois
