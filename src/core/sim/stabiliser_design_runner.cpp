#include "deep_ois/core/sim/stabiliser_design_runner.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"

namespace deep_ois {
namespace sim {

StabiliserModel designModel(const StabiliserDesign& design) {
  const GyroMountStage& mount = design.mount;
  const EstimatorStage& estimator = design.estimator;
  const ModeStage& mode = design.mode;
  const GainStage& gain = design.gain;
  const StrokeStage& stroke = design.stroke;
  const ActuatorStage& actuator = design.actuator;
  StabiliserModel model(std::vector<std::string>{});
  GyroLoopValues& loop = model.set(GyroLoopValues());
  loop.roll_deg = mount.roll_deg, loop.tilt_deg = mount.tilt_deg, loop.pan_deg = mount.pan_deg;
  loop.rate_hz = design.loop.rate_hz;
  loop.sampling = design.loop.sampling == GyroSampling::kAveraged ? "averaged" : "latest";
  MotionModeValues& motion = model.set(MotionModeValues());
  motion.action = toString(mode.action);
  motion.threshold_rad_s = mode.threshold_rad_s, motion.time_constant_s = mode.time_constant_s;
  motion.release_factor = mode.release_factor, motion.hold_time_constant_s = mode.hold_time_constant_s;
  motion.schedule_depth = gain.schedule_depth, motion.schedule_start_rad_s = gain.schedule_start_rad_s;
  motion.schedule_span_rad_s = gain.schedule_span_rad_s;
  motion.schedule_time_constant_s = gain.schedule_time_constant_s;
  IntendedMotionValues& intended = model.set(IntendedMotionValues());
  intended.kind = toString(estimator.kind);
  intended.corner_hz = estimator.corner_hz, intended.damping = estimator.damping;
  intended.rate_corner_hz = estimator.rate_corner_hz;
  intended.excursion_gain = estimator.excursion_gain, intended.excursion_power = estimator.excursion_power;
  intended.gain_x = gain.gain_x, intended.gain_y = gain.gain_y;
  TravelValues& travel = model.set(TravelValues());
  travel.shape = toString(stroke.kind);
  travel.x_positive_deg = stroke.x_positive_deg, travel.x_negative_deg = stroke.x_negative_deg;
  travel.y_positive_deg = stroke.y_positive_deg, travel.y_negative_deg = stroke.y_negative_deg;
  travel.anti_windup = toString(design.anti_windup.kind);
  travel.back_calculation_rate_per_s = design.anti_windup.back_calculation_rate_per_s;
  travel.quantiser_bits = static_cast<double>(design.output.quantiser_bits);
  HallActuatorValues& hall = model.set(HallActuatorValues());
  hall.delay_s = design.output.delay_s;
  hall.order = actuator.order == ActuatorOrder::kFirst ? "first" : "second";
  hall.bandwidth_hz = actuator.bandwidth_hz, hall.damping = actuator.damping;
  hall.rate_limit_deg_s = actuator.rate_limit_deg_s, hall.stiction_fraction = actuator.stiction_fraction;
  hall.end_stop_margin = actuator.end_stop_margin, hall.hall_c2 = design.hall.c2, hall.hall_c3 = design.hall.c3;
  return model;
}

StabiliserModel moduleModel(const OisConfig& config) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("ois: " + problem);
  const bool kalman = config.controller == "kalman";
  const bool digital = config.digital_rate_hz > 0.0;
  StabiliserModel model(std::vector<std::string>{});
  GyroLoopValues& loop = model.set(GyroLoopValues());
  loop.roll_deg = config.mount_rotation_deg;
  // A digital loop samples its newest gyro sample every `tick` control steps; a continuous one
  // integrates the rate over each step (its two samples' mean).
  const long tick =
      digital ? std::max(1L, std::lround(config.control_rate_hz / config.digital_rate_hz)) : 1L;
  loop.rate_hz = config.control_rate_hz / static_cast<double>(tick);
  loop.sampling = digital ? "latest" : "middle";
  if (!kalman && config.pan_detection_rate_rad_s > 0.0) {
    if (!(config.highpass_corner_hz > 0.0) ||
        config.pan_release_corner_hz < config.highpass_corner_hz)
      throw std::invalid_argument(
          "ois: pan detection needs pan_release_corner_hz >= highpass_corner_hz > 0");
    MotionModeValues& mode = model.set(MotionModeValues());
    mode.action = "release", mode.detector = "norm";
    mode.threshold_rad_s = config.pan_detection_rate_rad_s;
    mode.time_constant_s = config.pan_detection_time_constant_s;
    mode.release_factor = config.pan_release_corner_hz / config.highpass_corner_hz;
  }
  IntendedMotionValues& intended = model.set(IntendedMotionValues());
  intended.kind = kalman ? "kalman_cv" : "highpass_first_order";
  intended.corner_hz = kalman ? config.kalman_bandwidth_hz : config.highpass_corner_hz;
  intended.gain_x = intended.gain_y = config.gain;
  if (kalman) {
    intended.manoeuvre_deg = config.kalman_manoeuvre_deg;
    intended.manoeuvre_factor = config.kalman_manoeuvre_factor;
  } else {
    intended.excursion_gain = config.excursion_recentring_gain;
    intended.excursion_power = config.excursion_recentring_power;
  }
  TravelValues& travel = model.set(TravelValues());
  travel.shape = std::string(config.soft_stroke ? "soft_" : "") +
                 (config.stroke_shape == StrokeShape::kCircle ? "ellipse" : "box");
  travel.x_positive_deg = travel.x_negative_deg = config.stroke_limit_deg;
  travel.y_positive_deg = travel.y_negative_deg =
      config.stroke_limit_y_deg > 0.0 ? config.stroke_limit_y_deg : config.stroke_limit_deg;
  travel.quantiser_lsb_deg = config.command_lsb_deg;
  HallActuatorValues& hall = model.set(HallActuatorValues());
  hall.delay_s = config.hall_lag_s + config.digital_delay_s;
  const bool pi = config.position_loop == "pi";
  hall.order = pi ? "pi" : "second";
  hall.bandwidth_hz = pi ? config.pi_plant_natural_hz : config.actuator_natural_hz;
  hall.damping = pi ? config.pi_plant_damping : config.actuator_damping;
  hall.pi_kp = config.pi_kp, hall.pi_ki = config.pi_ki;
  hall.end_stop_margin = 1.0;  // the lens stops at the stroke
  if (config.actuator_cross_coupling != 0.0) {
    model.set(ActuatorCouplingValues()).actuator_coupling =
        Eigen::Vector2d::Constant(config.actuator_cross_coupling);
  }
  return model;
}

namespace {

// The chain of `model` stepped at rate_hz from start_s, from the camera-frame rate at each step's
// middle (its two samples' mean) and end, with the stabiliser's own sensors' noise put into the
// signal: per step the Hall reading's (drawn only when it has any), then its gyro's end sample;
// `start_sample` draws the gyro's sample at step 0 first (a controller that integrates between
// samples sees it).
LensShiftGrid runChain(const StabiliserModel& model, double focal_px, double start_s,
                       double rate_hz, int steps,
                       const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                       std::mt19937* noise, double gyro_noise_rad_s, double hall_noise_px,
                       bool start_sample) {
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || steps < 1) {
    throw std::invalid_argument("stabiliser: focal_px must be positive and steps at least 1");
  }
  const std::string problem = model.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser: " + problem);
  const double h = 1.0 / rate_hz;
  StabiliserChain chain(stabiliserRunners(model, {focal_px, h}));
  chain.reset();
  StabiliserSignal& signal = chain.signal();
  // One sensor's noise over a step: x drawn before y.
  auto draw = [&](double scale) -> Eigen::Vector2d {
    const double nx = gaussian(*noise);
    const double ny = gaussian(*noise);
    return scale * Eigen::Vector2d(nx, ny);
  };
  Eigen::Vector2d previous_noise = noise && start_sample ? draw(gyro_noise_rad_s) : Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> shifts(static_cast<std::size_t>(steps) + 1, Eigen::Vector2d::Zero());
  Eigen::Vector3d w = angular_velocity_rad_s(start_s);
  for (int j = 0; j < steps; ++j) {
    if (noise && hall_noise_px > 0.0) signal.hall_noise_px = draw(hall_noise_px);
    if (noise) {
      signal.gyro_noise_rad_s = draw(gyro_noise_rad_s);
      signal.gyro_noise_mid_rad_s = 0.5 * (previous_noise + signal.gyro_noise_rad_s);
      previous_noise = signal.gyro_noise_rad_s;
    }
    const Eigen::Vector3d next = angular_velocity_rad_s(start_s + (j + 1) * h);
    shifts[static_cast<std::size_t>(j) + 1] = chain.step(0.5 * (w + next), next);
    w = next;
  }
  return LensShiftGrid(start_s, rate_hz, std::move(shifts));
}

}  // namespace

LensShiftGrid runDesign(const StabiliserDesign& design, double focal_px, double start_s, int steps,
                        const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                        std::mt19937* noise) {
  const std::string problem = design.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser design: " + problem);
  return runChain(designModel(design), focal_px, start_s, kDesignPhysicsRateHz, steps,
                  angular_velocity_rad_s, noise, design.mount.noise_rad_s, design.hall.noise_px,
                  false);
}

// Sign of the cancelling shift and the discretisation: see OisModel (core/sim/ois_model.cpp).
LensShiftGrid runStabiliser(
    const OisConfig& config, double focal_px, double start_s, int steps,
    const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s, std::mt19937* noise) {
  return runChain(moduleModel(config), focal_px, start_s, config.control_rate_hz, steps,
                  angular_velocity_rad_s, noise, config.gyro_noise_rad_s, config.hall_noise_px,
                  true);
}

}  // namespace sim
}  // namespace deep_ois
