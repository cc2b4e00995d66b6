// Choosing a camera's stabiliser model by measurement: the physical chain fitted by
// core/ois/stabiliser_fit.h is the prior and the fallback; other compositions of stages are
// candidates, each scored on the held-out recordings, and the best is kept.
//
// Candidates, described as data (stabiliserCandidateDescriptions; cheap enough for the live
// budget: microseconds per frame at the gyro rate):
//  - "physical": the fitted chain alone (what fitStabiliser returns);
//  - the chain with a better structure, refitted (refitStabiliserStages): an integrator held at
//    the end stop (anti-windup), a re-centring corner that grows with the excursion, both; the
//    stroke in the actuator's own axes with a cross-coupling after the actuator (a turned or
//    coupled mount); a soft stroke (stroke x tanh(u / stroke)) instead of an end stop, alone and
//    with the excursion-dependent re-centring;
//  - a linear filter of free order of the three gyro axes (the linear_dynamics stage) instead of
//    the centring or beside it, composed with the stroke (hard or soft), the actuator and the
//    excursion-dependent re-centring, fitted in two steps (refitStabiliserStages).
// Pure C++/Eigen: no ROS.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/stabiliser_choice_rule.h"
#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

// A stabiliser model with a name for messages ("fit", "no lens motion", "generic", ...).
struct ModelCandidate {
  std::string name;
  StabiliserModel parameters;
};

// A candidate described as data: one row of the table stabiliserCandidates builds from. Its
// composition is a list of stage tokens (core/ois/stabiliser_stage.h, stabiliserComposition), in
// the chain's order: {"centring", "stroke:soft", "actuator"}. How the row is fitted follows from
// it:
//  - the chain's stages only (centring, stroke, actuator): the physical fit itself;
//  - another stage or a stroke variant: the chain refitted with it (refitStabiliserStages);
//  - linear_dynamics:BASIS (with or without other stages and variants): the listed chain in two
//    steps, the coefficients in closed form, then the whole chain jointly (refitStabiliserStages).
// Pan detection is the fit's choice for every row, so a row never names it.
struct StabiliserCandidateDescription {
  // What it adds to the chain, for its name ("anti-windup integrator"); "" for the chain itself.
  std::string name;
  std::vector<std::string> stages;
  // Simplest first: the choice rule keeps the simpler of two candidates within its margin
  // (stabiliser_choice_rule.h). "No lens motion" is 0.
  int complexity = 0;

  // A refit of the chain with a stage or variant more (the linear-dynamics stage aside: it is
  // linearDynamics(); a row with both is refitted as one with the linear stage).
  bool structural() const;
  // The linear-dynamics stage among its stages: fitted in two steps (refitStabiliserStages).
  bool linearDynamics() const;
};

// The candidate table, simplest first: the chain, the six structural variants, the five
// compositions with the linear-dynamics stage (the names and what each adds:
// docs/stabiliser_model.md).
const std::vector<StabiliserCandidateDescription>& stabiliserCandidateDescriptions();

// A model's place in the table's simplicity order, read from its parameters: 0 for "no lens
// motion", the complexity of the row that describes it (its stages; a linear filter added to the
// lens, an older file's converted residual bank, aside), and after every row for a composition no row describes (a hand-written file). So a model
// from anywhere (a prior, the model in use) is ranked as the candidates are.
int stabiliserComplexity(const StabiliserModel& parameters);

// Which rows stabiliserCandidates builds besides the physical chain.
struct StabiliserCandidateKinds {
  bool structural = true;        // the refitted structural variants (an LM refit each)
  // Solver iterations of each structural refit (0: the fit options' iterations). The
  // refits start from the fitted chain, so fewer suffice where time counts (the online learner).
  int structural_iterations = 0;
  // The linear-dynamics rows (one run of the chain per basis function and recording each).
  bool linear_dynamics = true;
};

// The candidates built from a physical fit (a fitStabiliser result), one per row of the table in
// its order (simplest first), unscored: "physical", then the kinds asked for. A row whose refit
// finds no usable lens motion is left out (the simpler ones stand).
std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds = {});

struct StabiliserCandidate {
  std::string name;
  StabiliserModel parameters;
  StabiliserScore training;  // scoreStabiliser (core/ois/stabiliser_fit.h)
  StabiliserScore held_out;  // observations 0 without held-out recordings
};

struct StabiliserSelection {
  std::vector<StabiliserCandidate> candidates;  // simplest first
  std::size_t kept = 0;
  std::string reason;  // one sentence: why candidates[kept] ("kept 'NAME': " + figures)
  std::string figures;  // the figures that chose it ("held-out lens-motion RMS 0.41 px, ...")
};

// Builds (stabiliserCandidates, `kinds`) and scores the candidates from the physical fit, and
// keeps one by the choice rule (stabiliser_choice_rule.h, no incumbent) on their held-out RMS (the
// training RMS when there are no held-out recordings: then said in the reason): the simplest
// within choice.simpler_within of the lowest.
StabiliserSelection selectStabiliser(const StabiliserFitResult& fit,
                                     const std::vector<StabiliserFitRecording>& training,
                                     const std::vector<StabiliserFitRecording>& held_out,
                                     const StabiliserFitOptions& options,
                                     const StabiliserChoiceOptions& choice = {},
                                     const StabiliserCandidateKinds& kinds = {});

}  // namespace deep_ois
