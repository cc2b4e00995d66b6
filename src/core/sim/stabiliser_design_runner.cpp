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
  // Each stage's values in the order its struct declares them (core/ois/stabiliser_model.h).
  const GyroMountStage& mount = design.mount;
  const EstimatorStage& estimator = design.estimator;
  const ModeStage& mode = design.mode;
  const GainStage& gain = design.gain;
  const StrokeStage& stroke = design.stroke;
  const ActuatorStage& actuator = design.actuator;
  StabiliserParameters p;
  p.gyro_loop = GyroLoopValues{mount.roll_deg, mount.tilt_deg, mount.pan_deg, design.loop.rate_hz,
                               design.loop.sampling == GyroSampling::kAveraged};
  p.motion_mode = MotionModeValues{toString(mode.action), mode.threshold_rad_s, mode.time_constant_s,
                                   mode.release_factor, mode.hold_time_constant_s, gain.schedule_depth,
                                   gain.schedule_start_rad_s, gain.schedule_span_rad_s,
                                   gain.schedule_time_constant_s};
  p.intended_motion = IntendedMotionValues{toString(estimator.kind), estimator.corner_hz, estimator.damping,
                                           estimator.rate_corner_hz, estimator.excursion_gain,
                                           estimator.excursion_power, gain.gain_x, gain.gain_y};
  p.travel = TravelValues{toString(stroke.kind), stroke.x_positive_deg, stroke.x_negative_deg,
                          stroke.y_positive_deg, stroke.y_negative_deg, toString(design.anti_windup.kind),
                          design.anti_windup.back_calculation_rate_per_s,
                          static_cast<double>(design.output.quantiser_bits)};
  p.hall_actuator = HallActuatorValues{design.output.delay_s, actuator.order == ActuatorOrder::kFirst ? "first" : "second",
                                       actuator.bandwidth_hz, actuator.damping, actuator.rate_limit_deg_s,
                                       actuator.stiction_fraction, actuator.end_stop_margin, design.hall.c2,
                                       design.hall.c3};
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
