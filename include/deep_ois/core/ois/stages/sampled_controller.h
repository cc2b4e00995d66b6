// The values of a sampled controller's stages, as the simulator's generated designs and committed
// camera modules are built (core/sim/stabiliser_design.h says what each mechanism does; its ranges
// bound them; core/sim/stabiliser_design_runner.h builds both):
// src/core/ois/stages/{gyro_loop,motion_mode,intended_motion,travel,hall_actuator}_stage.cpp.
// A model has such a stage when it holds its values. Words as the design names them.
#pragma once

#include <string>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct GyroLoopValues : StageValuesOf<GyroLoopValues> {  // its own gyro, when the controller samples it
  static constexpr const char* kStage = "gyro_loop";
  double roll_deg = 0.0, tilt_deg = 0.0, pan_deg = 0.0;  // camera -> gyro: roll, then tilt, pan
  double rate_hz = 4000.0;  // controller rate; the step's rate is a multiple of it
  // latest: the newest sample; averaged: the mean over its period; middle: the rate at the step's
  // middle (a continuous controller's trapezoid of two samples; rate_hz the step's rate).
  std::string sampling = "latest";
};
struct MotionModeValues : StageValuesOf<MotionModeValues> {  // pan detection, gain schedule
  static constexpr const char* kStage = "motion_mode";
  std::string action = "none";  // none, release, hold
  // vector: the norm of the low-passed rate (the shake averages out); norm: the low-passed norm of
  // the newest sample (a camera module's).
  std::string detector = "vector";
  double threshold_rad_s = 0.2, time_constant_s = 0.2, release_factor = 6.0, hold_time_constant_s = 0.1;
  double schedule_depth = 0.0;  // 0 = not scheduled
  double schedule_start_rad_s = 0.1, schedule_span_rad_s = 0.3, schedule_time_constant_s = 0.1;
};
struct IntendedMotionValues : StageValuesOf<IntendedMotionValues> {  // the angle to cancel, its gain
  static constexpr const char* kStage = "intended_motion";
  // highpass_first_order, highpass_second_order, velocity_loop, kalman_cv, alpha_beta
  std::string kind = "highpass_first_order";
  double corner_hz = 0.6, damping = 0.8, rate_corner_hz = 0.5;
  double excursion_gain = 0.0, excursion_power = 2.0;  // 0 = a fixed corner
  double gain_x = 1.0, gain_y = 1.0;
  // kalman_cv's manoeuvre gate (0 = none): an innovation above manoeuvre_deg multiplies the
  // process noise by manoeuvre_factor (intended_motion_tracker.h).
  double manoeuvre_deg = 0.0, manoeuvre_factor = 100.0;
};
struct TravelValues : StageValuesOf<TravelValues> {  // stroke per axis and direction, anti-windup, DAC
  static constexpr const char* kStage = "travel";
  std::string shape = "box";  // box, ellipse, soft_box, soft_ellipse
  double x_positive_deg = 1.0, x_negative_deg = 1.0, y_positive_deg = 1.0, y_negative_deg = 1.0;
  std::string anti_windup = "none";  // none, clamp, back_calculation
  double back_calculation_rate_per_s = 20.0;
  double quantiser_bits = 0.0;  // 0 = not quantised
  double quantiser_lsb_deg = 0.0;  // or the DAC's step as an angle (0 = by bits)
};
struct HallActuatorValues : StageValuesOf<HallActuatorValues> {  // delay, position loop, Hall sensor
  static constexpr const char* kStage = "hall_actuator";
  double delay_s = 0.0;
  // first, second, pi (a spring-mass lens of natural frequency bandwidth_hz and damping under a PI
  // loop of gains pi_kp and pi_ki 1/s)
  std::string order = "second";
  double bandwidth_hz = 35.0, damping = 0.7, rate_limit_deg_s = 0.0, stiction_fraction = 0.0;
  double pi_kp = 4.0, pi_ki = 300.0;
  double end_stop_margin = 1.1, hall_c2 = 0.0, hall_c3 = 0.0;
};

}  // namespace deep_ois
