// The registry of the stabiliser model's stages, in the order the signal passes them: adding a
// stage is its file (src/core/ois/stages/) and one line here (docs/stabiliser_model.md, "Adding a
// stage").
#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {

// Each defined in its own file.
const StabiliserStage& panDetectionStage();
const StabiliserStage& excursionCentringStage();
const StabiliserStage& centringStage();
const StabiliserStage& linearDynamicsStage();
const StabiliserStage& strokeStage();
const StabiliserStage& actuatorStage();
const StabiliserStage& actuatorCouplingStage();
const StabiliserStage& gyroLoopStage();
const StabiliserStage& motionModeStage();
const StabiliserStage& intendedMotionStage();
const StabiliserStage& travelStage();
const StabiliserStage& hallActuatorStage();

const std::vector<StabiliserStage>& stabiliserStages() {
  static const std::vector<StabiliserStage> stages = {
      gyroLoopStage(),          // the stabiliser's gyro, sampled by a controller
      panDetectionStage(),      // decides whether the angle re-centres fast (a pan)
      motionModeStage(),        // release or hold on a pan, gain schedule
      excursionCentringStage(), // scales the centring's corner with the excursion
      centringStage(),          // rate -> angle -> raw command
      intendedMotionStage(),    // sampled rate -> angle to cancel -> raw command
      linearDynamicsStage(),    // + a linear filter of the rate to the raw command
      strokeStage(),            // raw command -> command
      travelStage(),            // raw command -> command (asymmetric, anti-windup, DAC)
      actuatorStage(),          // command -> lens
      hallActuatorStage(),      // command -> delay -> position loop, Hall sensor -> lens
      actuatorCouplingStage(),  // the actuator's axes -> the image's
  };
  return stages;
}

const StabiliserStage& stabiliserStage(const std::string& name) {
  for (const StabiliserStage& stage : stabiliserStages())
    if (name == stage.name) return stage;
  std::string known;
  for (const StabiliserStage& stage : stabiliserStages())
    known += (known.empty() ? "" : ", ") + std::string(stage.name);
  throw std::invalid_argument("no stabiliser stage named '" + name + "' (known: " + known + ")");
}

const FittedStabiliserParameter& fittedStabiliserParameter(const std::string& name,
                                                           const StabiliserStage** stage) {
  for (const StabiliserStage& each : stabiliserStages())
    for (const FittedStabiliserParameter& parameter : each.fitted)
      if (name == parameter.name) {
        if (stage) *stage = &each;
        return parameter;
      }
  throw std::invalid_argument("no fitted stabiliser parameter named '" + name + "'");
}

double fittedValue(const FittedStabiliserParameter& parameter, const StabiliserModel& model) {
  for (const StageInstance& instance : model.stages())
    for (const FittedStabiliserParameter& each : instance.stage->fitted)
      if (&each == &parameter) return parameter.value(*instance.values);
  return std::numeric_limits<double>::quiet_NaN();
}

std::string stageOfToken(const std::string& token) { return token.substr(0, token.find(':')); }
std::string variantOfToken(const std::string& token) {
  const std::size_t colon = token.find(':');
  return colon == std::string::npos ? std::string() : token.substr(colon + 1);
}

std::vector<std::string> stabiliserComposition(const StabiliserModel& model) {
  std::vector<std::string> tokens;
  for (const StageInstance& instance : model.stages()) {
    const std::string token = instance.stage->token(*instance.values);
    if (!token.empty()) tokens.push_back(token);
  }
  return tokens;
}

std::vector<std::unique_ptr<StabiliserStageRunner>> stabiliserRunners(
    const StabiliserModel& model, const StabiliserRunContext& context) {
  std::vector<std::unique_ptr<StabiliserStageRunner>> runners;
  for (const StageInstance& instance : model.stages())
    if (auto runner = instance.stage->runner(*instance.values, model, context))
      runners.push_back(std::move(runner));
  return runners;
}

}  // namespace deep_ois
