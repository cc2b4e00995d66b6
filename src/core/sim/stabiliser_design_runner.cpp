#include "deep_ois/core/sim/stabiliser_design_runner.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {
namespace sim {

StabiliserParameters designModel(const StabiliserDesign& design) {
  StabiliserParameters p;
  GyroLoopValues& loop = p.gyro_loop.emplace();
  loop.roll_deg = design.mount.roll_deg;
  loop.tilt_deg = design.mount.tilt_deg;
  loop.pan_deg = design.mount.pan_deg;
  loop.rate_hz = design.loop.rate_hz;
  loop.averaged = design.loop.sampling == GyroSampling::kAveraged;
  MotionModeValues& mode = p.motion_mode.emplace();
  mode.action = toString(design.mode.action);
  mode.threshold_rad_s = design.mode.threshold_rad_s;
  mode.time_constant_s = design.mode.time_constant_s;
  mode.release_factor = design.mode.release_factor;
  mode.hold_time_constant_s = design.mode.hold_time_constant_s;
  mode.schedule_depth = design.gain.schedule_depth;
  mode.schedule_start_rad_s = design.gain.schedule_start_rad_s;
  mode.schedule_span_rad_s = design.gain.schedule_span_rad_s;
  mode.schedule_time_constant_s = design.gain.schedule_time_constant_s;
  IntendedMotionValues& estimator = p.intended_motion.emplace();
  estimator.kind = toString(design.estimator.kind);
  estimator.corner_hz = design.estimator.corner_hz;
  estimator.damping = design.estimator.damping;
  estimator.rate_corner_hz = design.estimator.rate_corner_hz;
  estimator.excursion_gain = design.estimator.excursion_gain;
  estimator.excursion_power = design.estimator.excursion_power;
  estimator.gain_x = design.gain.gain_x;
  estimator.gain_y = design.gain.gain_y;
  TravelValues& travel = p.travel.emplace();
  travel.shape = toString(design.stroke.kind);
  travel.x_positive_deg = design.stroke.x_positive_deg;
  travel.x_negative_deg = design.stroke.x_negative_deg;
  travel.y_positive_deg = design.stroke.y_positive_deg;
  travel.y_negative_deg = design.stroke.y_negative_deg;
  travel.anti_windup = toString(design.anti_windup.kind);
  travel.back_calculation_rate_per_s = design.anti_windup.back_calculation_rate_per_s;
  travel.quantiser_bits = design.output.quantiser_bits;
  HallActuatorValues& actuator = p.hall_actuator.emplace();
  actuator.delay_s = design.output.delay_s;
  actuator.order = design.actuator.order == ActuatorOrder::kFirst ? "first" : "second";
  actuator.bandwidth_hz = design.actuator.bandwidth_hz;
  actuator.damping = design.actuator.damping;
  actuator.rate_limit_deg_s = design.actuator.rate_limit_deg_s;
  actuator.stiction_fraction = design.actuator.stiction_fraction;
  actuator.end_stop_margin = design.actuator.end_stop_margin;
  actuator.hall_c2 = design.hall.c2;
  actuator.hall_c3 = design.hall.c3;
  p.stages = {"gyro_loop", "motion_mode", "intended_motion", "travel", "hall_actuator"};
  return p;
}

LensShiftGrid runDesign(const StabiliserDesign& design, double focal_px, double start_s, int steps,
                        const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                        std::mt19937* noise) {
  const std::string problem = design.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser design: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || steps < 1) {
    throw std::invalid_argument("runDesign: focal_px must be positive and steps at least 1");
  }
  const double h = 1.0 / kDesignPhysicsRateHz;
  StabiliserChain chain(stabiliserRunners(designModel(design), {focal_px, h}));
  chain.reset();
  StabiliserSignal& signal = chain.signal();
  std::vector<Eigen::Vector2d> shifts(static_cast<std::size_t>(steps) + 1, Eigen::Vector2d::Zero());
  for (int j = 0; j < steps; ++j) {
    // The sensors' noise in the order the simulator has always drawn it: the Hall reading's (only
    // when it has any), then the stabiliser gyro's.
    if (noise && design.hall.noise_px > 0.0) {
      const double nx = gaussian(*noise);
      const double ny = gaussian(*noise);
      signal.hall_noise_px = design.hall.noise_px * Eigen::Vector2d(nx, ny);
    }
    if (noise) {
      const double nx = gaussian(*noise);
      const double ny = gaussian(*noise);
      signal.gyro_noise_rad_s = design.mount.noise_rad_s * Eigen::Vector2d(nx, ny);
    }
    // The design's stages read the rate at the step's end (its gyro's sample).
    const Eigen::Vector3d w = angular_velocity_rad_s(start_s + (j + 1) * h);
    shifts[static_cast<std::size_t>(j) + 1] = chain.step(w, w);
  }
  return LensShiftGrid(start_s, kDesignPhysicsRateHz, std::move(shifts));
}

}  // namespace sim
}  // namespace deep_ois
