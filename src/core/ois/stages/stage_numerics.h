// Numerics the stages' runners share (core/ois/stabiliser_stage.h): the exact step of a leaky
// integrator, a sampled controller's tick, and the templates a stage's description is built from.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"

namespace deep_ois {
namespace stage_numerics {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// The leaky integrator y' = w - c y over one step of length h for the mean rate of the step:
// y <- decay y + weight w, exact for a rate held over the step.
inline double leakDecay(double corner_rad_s, double h) { return std::exp(-corner_rad_s * h); }
inline double leakWeight(double corner_rad_s, double h) {
  return corner_rad_s > 0.0 ? -std::expm1(-corner_rad_s * h) / corner_rad_s : h;
}

// The internal steps per update of a sampled controller (gyro_loop's rate; 1 without it). Throws
// std::invalid_argument when the rate is not the step's rate divided by a whole number.
inline long long controlTick(const StabiliserModel& model, const StabiliserRunContext& context) {
  const GyroLoopValues* loop = model.find<GyroLoopValues>();
  if (!loop) return 1;
  const double steps = 1.0 / (loop->rate_hz * context.step_s);
  const long long tick = std::llround(steps);
  if (tick < 1 || std::abs(steps - static_cast<double>(tick)) > 1e-6 * steps)
    throw std::invalid_argument("gyro_loop.rate_hz must divide the predictor's step rate");
  return tick;
}
// The controller's period (s): its tick of internal steps.
inline double controlPeriod(const StabiliserModel& model, const StabiliserRunContext& context) {
  return static_cast<double>(controlTick(model, context)) * context.step_s;
}

// A stage's values at their defaults (StabiliserStage::make).
template <typename Values>
std::unique_ptr<StageValues> make() {
  return std::make_unique<Values>();
}

// A stage's runner of type Runner, built from (its values, the model, context): the
// StabiliserStage::runner of a stage that always acts.
template <typename Runner, typename Values>
std::unique_ptr<StabiliserStageRunner> runner(const StageValues& own, const StabiliserModel& model,
                                              const StabiliserRunContext& context) {
  return std::make_unique<Runner>(valuesAs<Values>(own), model, context);
}

}  // namespace stage_numerics
}  // namespace deep_ois
