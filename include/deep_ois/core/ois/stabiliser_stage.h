// The stages of the stabiliser model (core/ois/stabiliser_model.h), each described once, in its
// own file under src/core/ois/stages/: the parameters it adds to StabiliserParameters with their
// names, units and the fit's bounds, its fields in the model file (core/ois/stabiliser_model_file.h),
// its validation, and its runner: the stage's state and its step over the signal that flows along
// the chain (StabiliserSignal below).
//
// Why stages and not code spread over the predictor, the fit, the file and validate(): a mechanism
// used to be written down in six places (the struct, the predictor's step, the fit's numbered
// parameter slots and clamps, the review's bounds, the file's reader and writer, validate()); each
// could disagree with the others. Now the predictor is a loop over the stages' runners, the fit
// builds its parameter vector from the stages' fitted parameters (by name), the review checks
// their bounds, and the file and validate() run over the stages.
//
// The stages, in the order the signal passes them (stabiliserStages()): gyro loop, pan detection,
// motion mode, excursion re-centring, centring (gain and corner), intended motion, linear
// dynamics, stroke (limits, shape, soft, anti-windup), travel, actuator (bandwidth, damping, sensor
// lag), Hall actuator, actuator coupling, linear residual, learned residual, learned lens dynamics.
// The gyro loop, motion mode, intended motion, travel and Hall actuator are a sampled controller's:
// the simulator's generated designs are built from them (core/sim/stabiliser_design_runner.h). docs/stabiliser_model.md ("The stage library") tabulates them for users and shows
// how to add one.
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
// when the stage is among those being fitted.
struct FittedStabiliserParameter {
  // As StabiliserParameters and the fit's review name it ("stroke_x_deg"; both components of a
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
  double (*value)(const StabiliserParameters& p);  // in `unit`
  void (*set)(StabiliserParameters* p, double value);
  // Whether the model uses it (its bound is reviewed only then); null: always.
  bool (*used)(const StabiliserParameters& p);
};

struct StabiliserStage {
  const char* name;         // "stroke"
  const char* description;  // one sentence for users
  // A stage of the physical chain (kept by StabiliserParameters::physicalChain()), or a residual or
  // learned stage on top of it (cleared there).
  bool physical;
  std::vector<FittedStabiliserParameter> fitted;  // in the fit's order
  // Its keys in the file's `stabiliser` section, for the documentation's table.
  std::vector<const char*> file_keys;
  // Writes its keys into the open `stabiliser` map (optional keys only when used, so files written
  // before a mechanism existed and files written now are the same bytes for the same model).
  void (*write)(YAML::Emitter& out, const StabiliserParameters& p);
  // Reads its keys from the `stabiliser` section into p; throws StabiliserModelFileError naming a
  // missing or malformed field. Optional keys absent: the mechanism off.
  void (*read)(const YAML::Node& section, StabiliserParameters* p);
  // Empty when its parameters are usable; otherwise a sentence naming the bad field.
  std::string (*validate)(const StabiliserParameters& p);
  // Takes the stage out (a residual or learned stage; null for the physical ones).
  void (*clear)(StabiliserParameters* p);
  // Its runner for p, or null when the stage does nothing for p (switched off). Throws
  // std::invalid_argument when it cannot run at the context's step.
  std::unique_ptr<StabiliserStageRunner> (*runner)(const StabiliserParameters& p,
                                                   const StabiliserRunContext& context);
  // Its word in a model's composition (stabiliserComposition, the candidates' lists): its name,
  // or name:variant ("stroke:soft"); empty when it does not act for p.
  std::string (*token)(const StabiliserParameters& p);
  // Sets the stage up in p as a refit starts it: `variant` "" is the plain stage, another its
  // variant (as in token), null the stage left out (switched off). Throws std::invalid_argument
  // for a variant it does not have. Null: the refit does not start it (always there, or fitted
  // otherwise).
  void (*start)(StabiliserParameters* p, const char* variant);
};

// Every stage, in the order the signal passes them (src/core/ois/stages/stabiliser_stages.cpp, the
// registry: one line per stage).
const std::vector<StabiliserStage>& stabiliserStages();
// The stage called `name` ("stroke"); throws std::invalid_argument for an unknown name.
const StabiliserStage& stabiliserStage(const std::string& name);

// The fitted parameter named `name` (its first component for a vector); throws
// std::invalid_argument for an unknown name.
const FittedStabiliserParameter& fittedStabiliserParameter(const std::string& name);

// The model's composition: the tokens of the stages that act for p, in the chain's order
// ({"centring", "stroke:anti_windup", "actuator", "linear_residual"}); what a candidate is written
// as (core/ois/stabiliser_candidates.h).
std::vector<std::string> stabiliserComposition(const StabiliserParameters& p);
// The stage name of a token ("stroke" for "stroke:soft") and its variant ("soft"; "" for none).
std::string stageOfToken(const std::string& token);
std::string variantOfToken(const std::string& token);

// The runners of every stage that acts for p, in the chain's order.
std::vector<std::unique_ptr<StabiliserStageRunner>> stabiliserRunners(
    const StabiliserParameters& p, const StabiliserRunContext& context);

}  // namespace deep_ois
