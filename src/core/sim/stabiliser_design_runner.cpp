#include "deep_ois/core/sim/stabiliser_design_runner.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
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
  loop.averaged = design.loop.sampling == GyroSampling::kAveraged;
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
