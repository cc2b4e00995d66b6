#include "deep_ois/core/ois/stabiliser_candidates.h"

#include "deep_ois/core/ois/lens_dynamics_adaptation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/ois/stabiliser_choice_rule.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"

namespace deep_ois {
StabiliserParameters fitNonlinearResidual(const StabiliserParameters& base,
                                          const std::vector<StabiliserFitRecording>& recordings,
                                          const StabiliserFitOptions& options,
                                          const std::string& feature_set, double ridge) {
  const long m = nonlinearFeatureCount(feature_set);
  if (m == 0) throw std::invalid_argument("nonlinear residual: unknown feature set '" + feature_set + "'");
  StabiliserParameters features_only = base;
  features_only.nonlinear_features = feature_set;
  features_only.nonlinear_residual.resize(0, 0);  // features computed, nothing added
  // Huber weights from what the chain leaves (the targets), the package's ridge convention: per
  // feature, relative to its own energy (the features differ by orders of magnitude).
  RobustRidgeRegression regression(m, 2, RobustLoss::huber(options.huber_px));
  for (const StabiliserFitRecording& recording : recordings) {
    if (recording.rates.empty() || recording.observations.empty()) continue;
    double span = 0.0;
    for (const LensMotionObservation& o : recording.observations)
      span = std::max(span, o.t_b_s - o.t_a_s);
    LensShiftPredictor predictor(features_only, recording.focal_px, options.step_s,
                                 std::max(0.25, 2.0 * span));
    predictor.max_gap_s = std::numeric_limits<double>::infinity();  // as the fit: gaps are fed
    predictor.recordFeatures();
    std::vector<std::size_t> order(recording.observations.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return recording.observations[a].t_b_s < recording.observations[b].t_b_s;
    });
    const double usable_from = recording.rates.front().stamp_s + options.warm_up_s;
    std::size_t next_rate = 0;
    for (std::size_t index : order) {
      const LensMotionObservation& o = recording.observations[index];
      while (next_rate < recording.rates.size() &&
             (!predictor.started() || predictor.newestStamp() < o.t_b_s)) {
        predictor.addRate(recording.rates[next_rate++]);
      }
      if (o.t_a_s < usable_from || !predictor.covers(o.t_a_s) || !predictor.covers(o.t_b_s))
        continue;
      const Eigen::VectorXd delta =
          recording.focal_px * (predictor.featuresAt(o.t_b_s) - predictor.featuresAt(o.t_a_s));
      const Eigen::Vector2d target =
          o.motion_px - (predictor.lensShiftAt(o.t_b_s) - predictor.lensShiftAt(o.t_a_s));
      regression.add(delta, target, o.weight, target.norm());
    }
  }
  if (regression.count() == 0) throw std::invalid_argument("nonlinear residual: no usable lens motion");
  Eigen::MatrixXd solution;  // m x 2
  StabiliserParameters fitted = base;
  if (!regression.solve(ridge, &solution)) return fitted;
  fitted.nonlinear_features = feature_set;
  // The predictor multiplies by focal_px itself; the deltas above already carry it.
  fitted.nonlinear_residual = solution.transpose();
  return fitted;
}

const std::vector<StabiliserCandidateDescription>& stabiliserCandidateDescriptions() {
  // One mechanism or one feature set more per row, simplest first. The structural rows are the
  // chain itself with another mechanism (an integrator held at the end stop; a re-centring that
  // grows with the excursion; the stroke in the actuator's axes with their coupling after it; a
  // soft stroke instead of an end stop), refitted from the fitted chain's parameters; the learned
  // rows add dynamics on top of the fitted chain (with its linear bank when it has one): a
  // higher-order linear filter of the rate, nonlinear functions of the chain's state, both.
  using S = StabiliserStructure;
  static const std::vector<StabiliserCandidateDescription> table = {
      {"", S{}, false, "", 1},
      {"linear residual", S{}, true, "", 2},
      {"anti-windup integrator", S{true, false, false, false}, true, "", 3},
      {"excursion-dependent re-centring", S{false, true, false, false}, true, "", 4},
      {"anti-windup integrator + excursion-dependent re-centring", S{true, true, false, false}, true, "", 5},
      {"stroke in the actuator's axes + actuator coupling", S{false, false, true, false}, true, "", 6},
      {"soft stroke", S{false, false, false, true}, true, "", 7},
      {"soft stroke + excursion-dependent re-centring", S{false, true, false, true}, true, "", 8},
      {"learned rate filter", S{}, true, "rate_bank_v1", 9},
      {"nonlinear residual", S{}, true, "excursion_v1", 10},
      {"nonlinear residual + learned rate filter", S{}, true, "excursion_rate_v1", 11},
  };
  return table;
}

namespace {

bool sameStructure(const StabiliserStructure& a, const StabiliserStructure& b) {
  return a.anti_windup == b.anti_windup && a.excursion_centring == b.excursion_centring &&
         a.actuator_coupling == b.actuator_coupling && a.soft_stroke == b.soft_stroke;
}

}  // namespace

bool StabiliserCandidateDescription::structural() const {
  return !sameStructure(structure, StabiliserStructure{});
}

int stabiliserComplexity(const StabiliserParameters& parameters) {
  if (isNoLensMotion(parameters)) return 0;
  const StabiliserStructure structure{parameters.anti_windup, parameters.excursion_centring > 0.0,
                                      !parameters.actuator_coupling.isZero(0.0), parameters.soft_stroke};
  const bool linear = parameters.residual.size() != 0;
  int most = 0;
  for (const StabiliserCandidateDescription& d : stabiliserCandidateDescriptions())
    most = std::max(most, d.complexity);
  // A learned network (alone or on the chain's residual) is more than any row or hand-written
  // composition: kept only when it beats every simpler candidate by the rule's margin.
  if (parameters.learned_dynamics.active()) return most + 2;
  for (const StabiliserCandidateDescription& d : stabiliserCandidateDescriptions()) {
    // A refitted structure keeps its bank only when the bank helps: either way it is that row.
    if (sameStructure(d.structure, structure) && d.feature_set == parameters.nonlinear_features &&
        (d.structural() || d.linear_residual == linear || !d.feature_set.empty()))
      return d.complexity;
  }
  return most + 1;  // a composition no row describes (a hand-written file): after every row
}

std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds) {
  std::vector<ModelCandidate> candidates;
  const bool has_linear = fit.parameters.residual.size() != 0;
  StabiliserFitOptions refit_options = options;
  if (kinds.structural_iterations > 0) refit_options.iterations = kinds.structural_iterations;
  std::vector<StabiliserCandidateDescription> rows = stabiliserCandidateDescriptions();
  std::stable_sort(rows.begin(), rows.end(),
                   [](const auto& a, const auto& b) { return a.complexity < b.complexity; });
  for (const StabiliserCandidateDescription& row : rows) {
    if (row.structural() && !kinds.structural) continue;
    if (!row.feature_set.empty() && !kinds.learned_features) continue;
    try {
      if (row.structural()) {
        const StabiliserFitResult refit =
            refitStabiliserStructure(fit.parameters, row.structure, training, refit_options);
        candidates.push_back(
            {std::string(refit.parameters.residual.size() != 0 ? "physical + linear" : "physical") + ", " +
                 row.name,
             refit.parameters});
      } else if (!row.feature_set.empty()) {
        const std::string prefix = has_linear ? "physical + linear + " : "physical + ";
        candidates.push_back({prefix + row.name + " (" + row.feature_set + ")",
                              fitNonlinearResidual(fit.parameters, training, options, row.feature_set)});
      } else if (row.linear_residual) {
        if (has_linear) candidates.push_back({"physical + " + row.name, fit.parameters});
      } else {
        candidates.push_back({"physical", fit.parameters.physicalChain()});
      }
    } catch (const std::invalid_argument&) {
      // No usable lens motion for the refit or the residual: the simpler candidates stand.
    }
  }
  // The generic learned lens dynamics, adapted to this camera: its conditioning vector, then with
  // the map of its lens (scale and axes) as well.
  if (kinds.lens_dynamics) {
    LensDynamicsAdaptationOptions adaptation;
    adaptation.iterations = kinds.lens_dynamics_iterations;
    try {
      adaptation.fit_output_map = false;
      StabiliserParameters adapted =
          adaptLensDynamics(kinds.lens_dynamics, training, options, adaptation).parameters;
      candidates.push_back({"generic lens dynamics, adapted", adapted});
      if (kinds.lens_dynamics_map) {
        adaptation.fit_output_map = true;
        adapted = adaptLensDynamics(kinds.lens_dynamics, training, options, adaptation).parameters;
        candidates.push_back({"generic lens dynamics, adapted + lens map", adapted});
      }
      // Then its output layer refitted to the camera (a linear map from the network's state).
      candidates.push_back({"generic lens dynamics, adapted + output layer refitted",
                            refitLensDynamicsOutput(adapted, training, options)});
    } catch (const std::invalid_argument&) {
      // No usable lens motion: the simpler candidates stand.
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
