#include "deep_ois/core/ois/stabiliser_candidates.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/ois/stabiliser_choice_rule.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"
#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {
const std::vector<StabiliserCandidateDescription>& stabiliserCandidateDescriptions() {
  // One mechanism more per row, simplest first. The structural rows are the chain itself with
  // another mechanism (an integrator held at the end stop; a re-centring that grows with the
  // excursion; the stroke in the actuator's axes with their coupling after it; a soft stroke
  // instead of an end stop), refitted from the fitted chain's parameters.
  static const std::vector<StabiliserCandidateDescription> table = {
      {"", {"centring", "stroke", "actuator"}, 1},
      {"anti-windup integrator", {"centring", "stroke:anti_windup", "actuator"}, 2},
      {"excursion-dependent re-centring", {"excursion_centring", "centring", "stroke", "actuator"}, 3},
      {"anti-windup integrator + excursion-dependent re-centring",
       {"excursion_centring", "centring", "stroke:anti_windup", "actuator"}, 4},
      {"stroke in the actuator's axes + actuator coupling",
       {"centring", "stroke", "actuator", "actuator_coupling"}, 5},
      {"soft stroke", {"centring", "stroke:soft", "actuator"}, 6},
      {"soft stroke + excursion-dependent re-centring",
       {"excursion_centring", "centring", "stroke:soft", "actuator"}, 7},
      // The linear-dynamics stage (its basis as the token's variant: poles in Hz, functions per
      // axis) instead of the centring or beside it, fitted in two steps (refitStabiliserStages).
      // Without an actuator the basis carries the actuator's dynamics too: a fast second pole.
      // Kept as chosen on training designs (docs/results/stabiliser_model.md): the rows with the
      // actuator and a hard stroke, and with the anti-windup integrator, were never the best.
      {"linear dynamics + stroke", {"linear_dynamics:1+10hz_x16", "stroke"}, 8},
      {"linear dynamics + soft stroke + actuator", {"linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 9},
      {"centring + linear dynamics", {"centring", "linear_dynamics:1hz_x8", "stroke", "actuator"}, 10},
      {"centring + linear dynamics + soft stroke",
       {"centring", "linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 11},
      {"excursion-dependent re-centring + linear dynamics + soft stroke",
       {"excursion_centring", "centring", "linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 12},
  };
  return table;
}

namespace {

bool has(const std::vector<std::string>& tokens, const std::string& token) {
  return std::find(tokens.begin(), tokens.end(), token) != tokens.end();
}

// The composition without what no row names: pan detection (chosen for every row) and the
// linear filter added to the lens that an older file's residual bank converts to (such a model
// ranks as the chain under it, as its bank did).
std::vector<std::string> comparable(std::vector<std::string> tokens) {
  tokens.erase(std::remove_if(tokens.begin(), tokens.end(),
                              [&](const std::string& t) {
                                return t == "pan_detection" || t.rfind("linear_dynamics:lens_", 0) == 0;
                              }),
               tokens.end());
  std::sort(tokens.begin(), tokens.end());  // the row's order is the chain's, not the match's
  return tokens;
}

}  // namespace

bool StabiliserCandidateDescription::structural() const {
  for (const std::string& token : stages)
    if (!has({"centring", "stroke", "actuator"}, token) && stageOfToken(token) != "linear_dynamics")
      return true;
  return false;
}

bool StabiliserCandidateDescription::linearDynamics() const {
  return std::any_of(stages.begin(), stages.end(),
                     [](const std::string& token) { return stageOfToken(token) == "linear_dynamics"; });
}

int stabiliserComplexity(const StabiliserModel& parameters) {
  if (isNoLensMotion(parameters)) return 0;
  const std::vector<std::string> composition = stabiliserComposition(parameters);
  int most = 0;
  for (const StabiliserCandidateDescription& d : stabiliserCandidateDescriptions())
    most = std::max(most, d.complexity);
  for (const StabiliserCandidateDescription& d : stabiliserCandidateDescriptions())
    if (comparable(d.stages) == comparable(composition)) return d.complexity;
  return most + 1;  // a composition no row describes (a hand-written file): after every row
}

std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds) {
  std::vector<ModelCandidate> candidates;
  StabiliserFitOptions refit_options = options;
  if (kinds.structural_iterations > 0) refit_options.iterations = kinds.structural_iterations;
  std::vector<StabiliserCandidateDescription> rows = stabiliserCandidateDescriptions();
  std::stable_sort(rows.begin(), rows.end(),
                   [](const auto& a, const auto& b) { return a.complexity < b.complexity; });
  for (const StabiliserCandidateDescription& row : rows) {
    if (row.structural() && !kinds.structural) continue;
    if (row.linearDynamics() && !kinds.linear_dynamics) continue;
    try {
      if (row.linearDynamics()) {
        // The two-step fit: the coefficients in closed form, then the whole chain jointly.
        candidates.push_back(
            {row.name, refitStabiliserStages(fit.parameters, row.stages, training, refit_options).parameters});
      } else if (row.structural()) {
        candidates.push_back(
            {"physical, " + row.name,
             refitStabiliserStages(fit.parameters, row.stages, training, refit_options).parameters});
      } else {
        candidates.push_back({"physical", fit.parameters});
      }
    } catch (const std::invalid_argument&) {
      // No usable lens motion for the refit: the simpler candidates stand.
    }
  }
  return candidates;
}

StabiliserSelection selectStabiliser(const StabiliserFitResult& fit,
                                     const std::vector<StabiliserFitRecording>& training,
                                     const std::vector<StabiliserFitRecording>& held_out,
                                     const StabiliserFitOptions& options,
                                     const StabiliserChoiceOptions& choice,
                                     const StabiliserCandidateKinds& kinds) {
  StabiliserSelection selection;
  for (ModelCandidate& built : stabiliserCandidates(fit, training, options, kinds)) {
    StabiliserCandidate candidate;
    candidate.name = std::move(built.name);
    candidate.parameters = std::move(built.parameters);
    candidate.training = scoreStabiliser(candidate.parameters, training, options);
    candidate.held_out = scoreStabiliser(candidate.parameters, held_out, options);
    selection.candidates.push_back(std::move(candidate));
  }
  const bool by_held_out = !held_out.empty() && selection.candidates.front().held_out.observations > 0;
  std::vector<RankedScore> scores;
  for (const StabiliserCandidate& c : selection.candidates) {
    RankedScore score;
    score.rms_px = by_held_out ? c.held_out.rms_px : c.training.rms_px;
    score.complexity = stabiliserComplexity(c.parameters);
    score.no_lens_motion = isNoLensMotion(c.parameters);
    scores.push_back(score);
  }
  const StabiliserRuling ruling = applyStabiliserChoiceRule(scores, kNoIncumbent, choice);
  const std::size_t kept = ruling.chosen, best = ruling.lowest;
  selection.kept = kept;
  auto key = [&](std::size_t k) { return scores[k].rms_px; };
  std::ostringstream why;
  why.precision(4);
  why << (by_held_out ? "held-out" : "training (no held-out recordings, so no test of "
                                     "generalisation)")
      << " lens-motion RMS " << key(kept) << " px";
  if (kept != best) {
    why << ", within " << 100.0 * choice.simpler_within << " % of the best ('"
        << selection.candidates[best].name << "', " << key(best) << " px) and simpler";
  } else if (selection.candidates.size() > 1) {
    why << ", the lowest of " << selection.candidates.size() << " candidates";
  }
  selection.figures = why.str();
  selection.reason = "kept '" + selection.candidates[kept].name + "': " + selection.figures;
  return selection;
}

}  // namespace deep_ois
