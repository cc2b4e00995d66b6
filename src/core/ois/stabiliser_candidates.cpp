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
#include "deep_ois/core/ois/stages/learned_residual.h"
#include "deep_ois/core/ois/stages/linear_residual.h"

namespace deep_ois {
StabiliserModel fitNonlinearResidual(const StabiliserModel& base,
                                          const std::vector<StabiliserFitRecording>& recordings,
                                          const StabiliserFitOptions& options,
                                          const std::string& feature_set, double ridge) {
  const long m = nonlinearFeatureCount(feature_set);
  if (m == 0) throw std::invalid_argument("nonlinear residual: unknown feature set '" + feature_set + "'");
  StabiliserModel features_only = base;
  LearnedResidualValues& features = features_only.get<LearnedResidualValues>();
  features.nonlinear_features = feature_set;
  features.nonlinear_residual.resize(0, 0);  // features computed, nothing added
  // Huber weights from what the chain leaves (the targets), the package's ridge convention: per
  // feature, relative to its own energy (the features differ by orders of magnitude).
  RobustRidgeRegression regression(m, 2, RobustLoss::huber(options.huber_px));
  for (const StabiliserFitRecording& recording : recordings) {
    visitCoveredObservations(
        features_only, recording, options.step_s, options.warm_up_s,
        [&](const LensShiftPredictor& predictor, std::size_t index) {
          const LensMotionObservation& o = recording.observations[index];
          const Eigen::VectorXd delta =
              recording.focal_px * (predictor.featuresAt(o.t_b_s) - predictor.featuresAt(o.t_a_s));
          const Eigen::Vector2d target =
              o.motion_px - (predictor.lensShiftAt(o.t_b_s) - predictor.lensShiftAt(o.t_a_s));
          regression.add(delta, target, o.weight, target.norm());
        },
        [](LensShiftPredictor& predictor) { predictor.recordFeatures(); });
  }
  if (regression.count() == 0) throw std::invalid_argument("nonlinear residual: no usable lens motion");
  Eigen::MatrixXd solution;  // m x 2
  StabiliserModel fitted = base;
  if (!regression.solve(ridge, &solution)) return fitted;
  LearnedResidualValues& learned = fitted.get<LearnedResidualValues>();
  learned.nonlinear_features = feature_set;
  // The predictor multiplies by focal_px itself; the deltas above already carry it.
  learned.nonlinear_residual = solution.transpose();
  return fitted;
}

const std::vector<StabiliserCandidateDescription>& stabiliserCandidateDescriptions() {
  // One mechanism or one feature set more per row, simplest first. The structural rows are the
  // chain itself with another mechanism (an integrator held at the end stop; a re-centring that
  // grows with the excursion; the stroke in the actuator's axes with their coupling after it; a
  // soft stroke instead of an end stop), refitted from the fitted chain's parameters; the learned
  // rows add dynamics on top of the fitted chain (with its linear bank when it has one): a
  // higher-order linear filter of the rate, nonlinear functions of the chain's state, both.
  static const std::vector<StabiliserCandidateDescription> table = {
      {"", {"centring", "stroke", "actuator"}, 1},
      {"linear residual", {"centring", "stroke", "actuator", "linear_residual"}, 2},
      {"anti-windup integrator", {"centring", "stroke:anti_windup", "actuator", "linear_residual"}, 3},
      {"excursion-dependent re-centring",
       {"excursion_centring", "centring", "stroke", "actuator", "linear_residual"}, 4},
      {"anti-windup integrator + excursion-dependent re-centring",
       {"excursion_centring", "centring", "stroke:anti_windup", "actuator", "linear_residual"}, 5},
      {"stroke in the actuator's axes + actuator coupling",
       {"centring", "stroke", "actuator", "actuator_coupling", "linear_residual"}, 6},
      {"soft stroke", {"centring", "stroke:soft", "actuator", "linear_residual"}, 7},
      {"soft stroke + excursion-dependent re-centring",
       {"excursion_centring", "centring", "stroke:soft", "actuator", "linear_residual"}, 8},
      {"learned rate filter",
       {"centring", "stroke", "actuator", "linear_residual", "learned_residual:rate_bank_v1"}, 9},
      {"nonlinear residual",
       {"centring", "stroke", "actuator", "linear_residual", "learned_residual:excursion_v1"}, 10},
      {"nonlinear residual + learned rate filter",
       {"centring", "stroke", "actuator", "linear_residual", "learned_residual:excursion_rate_v1"}, 11},
      // The linear-dynamics stage (its basis as the token's variant: poles in Hz, functions per
      // axis) instead of the centring or beside it, fitted in two steps (refitStabiliserStages).
      // Without an actuator the basis carries the actuator's dynamics too: a fast second pole.
      // Kept as chosen on training designs (docs/results/stabiliser_model.md): the rows with the
      // actuator and a hard stroke, and with the anti-windup integrator, were never the best.
      {"linear dynamics + stroke", {"linear_dynamics:1+10hz_x16", "stroke"}, 12},
      {"linear dynamics + soft stroke + actuator", {"linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 13},
      {"centring + linear dynamics", {"centring", "linear_dynamics:1hz_x8", "stroke", "actuator"}, 14},
      {"centring + linear dynamics + soft stroke",
       {"centring", "linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 15},
      {"excursion-dependent re-centring + linear dynamics + soft stroke",
       {"excursion_centring", "centring", "linear_dynamics:1hz_x8", "stroke:soft", "actuator"}, 16},
  };
  return table;
}

namespace {

bool has(const std::vector<std::string>& tokens, const std::string& token) {
  return std::find(tokens.begin(), tokens.end(), token) != tokens.end();
}

// The composition without what a row leaves to the fit: pan detection (chosen for every row) and,
// for a refit or a learned residual, the linear bank (kept only where it helps, or under it).
std::vector<std::string> comparable(std::vector<std::string> tokens, bool without_bank) {
  tokens.erase(std::remove_if(tokens.begin(), tokens.end(),
                              [&](const std::string& t) {
                                return t == "pan_detection" || (without_bank && t == "linear_residual");
                              }),
               tokens.end());
  std::sort(tokens.begin(), tokens.end());  // the row's order is the chain's, not the match's
  return tokens;
}

}  // namespace

std::string StabiliserCandidateDescription::featureSet() const {
  for (const std::string& token : stages)
    if (stageOfToken(token) == "learned_residual") return variantOfToken(token);
  return {};
}

bool StabiliserCandidateDescription::structural() const {
  for (const std::string& token : stages)
    if (!has({"centring", "stroke", "actuator", "linear_residual"}, token) &&
        stageOfToken(token) != "learned_residual" && stageOfToken(token) != "linear_dynamics")
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
  for (const StabiliserCandidateDescription& d : stabiliserCandidateDescriptions()) {
    // A refit keeps its bank only when the bank helps: either way it is that row.
    const bool without_bank = d.structural() || !d.featureSet().empty();
    if (comparable(d.stages, without_bank) == comparable(composition, without_bank))
      return d.complexity;
  }
  return most + 1;  // a composition no row describes (a hand-written file): after every row
}

std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds) {
  std::vector<ModelCandidate> candidates;
  const bool has_linear = has(stabiliserComposition(fit.parameters), "linear_residual");
  StabiliserFitOptions refit_options = options;
  if (kinds.structural_iterations > 0) refit_options.iterations = kinds.structural_iterations;
  std::vector<StabiliserCandidateDescription> rows = stabiliserCandidateDescriptions();
  std::stable_sort(rows.begin(), rows.end(),
                   [](const auto& a, const auto& b) { return a.complexity < b.complexity; });
  for (const StabiliserCandidateDescription& row : rows) {
    const std::string feature_set = row.featureSet();
    if (row.structural() && !kinds.structural) continue;
    if (!feature_set.empty() && !kinds.learned_features) continue;
    if (row.linearDynamics() && !kinds.linear_dynamics) continue;
    try {
      if (row.linearDynamics()) {
        // The two-step fit: the coefficients in closed form, then the whole chain jointly.
        candidates.push_back(
            {row.name, refitStabiliserStages(fit.parameters, row.stages, training, refit_options).parameters});
      } else if (row.structural()) {
        const StabiliserFitResult refit =
            refitStabiliserStages(fit.parameters, row.stages, training, refit_options);
        candidates.push_back(
            {std::string(has(stabiliserComposition(refit.parameters), "linear_residual")
                             ? "physical + linear"
                             : "physical") +
                 ", " +
                 row.name,
             refit.parameters});
      } else if (!feature_set.empty()) {
        const std::string prefix = has_linear ? "physical + linear + " : "physical + ";
        candidates.push_back({prefix + row.name + " (" + feature_set + ")",
                              fitNonlinearResidual(fit.parameters, training, options, feature_set)});
      } else if (has(row.stages, "linear_residual")) {
        if (has_linear) candidates.push_back({"physical + " + row.name, fit.parameters});
      } else {
        candidates.push_back({"physical", fit.parameters.physicalChain()});
      }
    } catch (const std::invalid_argument&) {
      // No usable lens motion for the refit or the residual: the simpler candidates stand.
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
