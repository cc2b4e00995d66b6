// The stages of the stabiliser model (core/ois/stabiliser_model.h), each described once, in its
// own file under src/core/ois/stages/: its values (a StageValues type), the parameters the fit
// moves with their names, units and bounds, its fields in the model file
// (core/ois/stabiliser_model_file.h), its validation, and its runner: the stage's state and its
// step over the signal that flows along the chain (StabiliserSignal).
//
// Why stages and not code spread over the predictor, the fit, the file and validate(): a mechanism
// used to be written down in six places (a struct of every mechanism's fields, the predictor's
// step, the fit's numbered parameter slots and clamps, the review's bounds, the file's reader and
// writer, validate()); each could disagree with the others. Now a model is a list of stages with
// their values, the predictor is a loop over their runners, the fit builds its parameter vector
// from the stages' fitted parameters (by name), the review checks their bounds, and the file and
// validate() run over the stages.
//
// The stages, in the order the signal passes them (stabiliserStages()): gyro loop, pan detection,
// motion mode, excursion re-centring, centring (gain and corner), intended motion, linear
// dynamics, stroke (limits, shape, soft, anti-windup), travel, actuator (bandwidth, damping, sensor
// lag), Hall actuator, actuator coupling.
// The gyro loop, motion mode, intended motion, travel and Hall actuator are a sampled controller's:
// the simulator's generated designs and camera modules are built from them
// (core/sim/stabiliser_design_runner.h).
// docs/stabiliser_model.md ("The stage library") tabulates them for users and shows how to add one.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace YAML {
class Emitter;
class Node;
}  // namespace YAML

namespace deep_ois {

// One scalar parameter a stage lets the Levenberg-Marquardt fit move (core/ois/stabiliser_fit.h),
// when the stage is among those being fitted: an accessor on the stage's own values.
struct FittedStabiliserParameter {
  // As the fit's review and the training report name it ("stroke_x_deg"; both components of a
  // vector share its name, "actuator_coupling").
  const char* name;
  const char* what;  // in words, for the review: "stroke x"
  const char* unit;  // of value(), the bounds and the review ("Hz", "ms", "deg"; "" = unitless)
  // The fit moves log(value) (a positive scale: corners, strokes) or the value itself.
  bool logarithmic;
  // The fit keeps the value in [lower, upper] (in `unit`); a value that ends on one wanted to go
  // further and the review says so. +-infinity: unbounded.
  double lower, upper;
  double fit_step;  // the forward-difference step of the fit's Jacobian, in the fit's coordinate
  double (*value)(const StageValues& own);  // in `unit`
  void (*set)(StageValues& own, double value);
  // Whether the model uses it (its bound is reviewed only then); null: always.
  bool (*used)(const StageValues& own);
};

// A stage: everything about one mechanism, in its own file under src/core/ois/stages/. The
// functions act on the stage's own values (the StageValues type its file declares); those that
// need another stage's (the stroke's anti-windup reads the centring's gain) also get the model.
struct StabiliserStage {
  const char* name;         // "stroke"
  const char* description;  // one sentence for users
  // In a default-constructed model (and in a model file that names no stage list).
  bool in_default_chain;
  std::vector<FittedStabiliserParameter> fitted;  // in the fit's order
  // Its keys in the file's `stabiliser` section, for the documentation's table.
  std::vector<const char*> file_keys;
  // Its values at their defaults.
  std::unique_ptr<StageValues> (*make)();
  // Writes its keys into the open `stabiliser` map (optional keys only when used, so files written
  // before a mechanism existed and files written now are the same bytes for the same model).
  void (*write)(YAML::Emitter& out, const StageValues& own);
  // Reads its keys from the `stabiliser` section; throws StabiliserModelFileError naming a missing
  // or malformed field. Optional keys absent: the mechanism off. False when the file has not got
  // the stage at all (a sampled controller's stage without its map).
  bool (*read)(const YAML::Node& section, StageValues& own);
  // Empty when its values are usable; otherwise a sentence naming the bad field.
  std::string (*validate)(const StageValues& own, const StabiliserModel& model);
  // Its runner, or null when the stage does nothing for its values (switched off). Throws
  // std::invalid_argument when it cannot run at the context's step.
  std::unique_ptr<StabiliserStageRunner> (*runner)(const StageValues& own, const StabiliserModel& model,
                                                   const StabiliserRunContext& context);
  // Its word in a model's composition (stabiliserComposition, the candidates' lists): its name,
  // or name:variant ("stroke:soft"); empty when it does not act.
  std::string (*token)(const StageValues& own);
  // Sets the stage up as a refit starts it: `variant` "" is the plain stage, another its variant
  // (as in token), null the stage left out (switched off). Throws std::invalid_argument for a
  // variant it does not have. Null: the refit does not start it (always there, or fitted
  // otherwise).
  void (*start)(StageValues& own, const char* variant);
};

// A stage's own values as its type (the stage's functions get them as StageValues).
template <typename V>
const V& valuesAs(const StageValues& own) { return static_cast<const V&>(own); }
template <typename V>
V& valuesAs(StageValues& own) { return static_cast<V&>(own); }

// Every stage, in the order the signal passes them (src/core/ois/stages/stabiliser_stages.cpp, the
// registry: one line per stage).
const std::vector<StabiliserStage>& stabiliserStages();
// The stage called `name` ("stroke"); throws std::invalid_argument for an unknown name.
const StabiliserStage& stabiliserStage(const std::string& name);

// The fitted parameter named `name` (its first component for a vector); throws
// std::invalid_argument for an unknown name. `stage`, when given, is set to its stage.
const FittedStabiliserParameter& fittedStabiliserParameter(const std::string& name,
                                                           const StabiliserStage** stage = nullptr);
// Its value in the model (NaN when the model has not got its stage).
double fittedValue(const FittedStabiliserParameter& parameter, const StabiliserModel& model);

// The model's composition: the tokens of the stages that act, in the chain's order
// ({"centring", "stroke:anti_windup", "actuator", "linear_dynamics:1hz_x8"}); what a candidate is written
// as (core/ois/stabiliser_candidates.h).
std::vector<std::string> stabiliserComposition(const StabiliserModel& model);
// The stage name of a token ("stroke" for "stroke:soft") and its variant ("soft"; "" for none).
std::string stageOfToken(const std::string& token);
std::string variantOfToken(const std::string& token);

// The runners of every stage that acts in the model, in the chain's order.
std::vector<std::unique_ptr<StabiliserStageRunner>> stabiliserRunners(
    const StabiliserModel& model, const StabiliserRunContext& context);

}  // namespace deep_ois
