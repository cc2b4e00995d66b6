#include "deep_ois/core/ois/stabiliser_candidates.h"

#include "deep_ois/core/ois/lens_dynamics_adaptation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

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
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(m, 2);
  std::size_t used = 0;
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
      const double norm = target.norm();
      const double w = std::max(0.0, o.weight) *
                       (norm <= options.huber_px ? 1.0 : options.huber_px / norm);
      A.noalias() += w * delta * delta.transpose();
      B.noalias() += w * delta * target.transpose();
      ++used;
    }
  }
  if (used == 0) throw std::invalid_argument("nonlinear residual: no usable lens motion");
  // Ridge per feature, relative to its own energy (the features differ by orders of magnitude).
  const double floor = 1e-12 * std::max(1e-300, A.diagonal().maxCoeff());
  for (long k = 0; k < m; ++k) A(k, k) += ridge * A(k, k) + floor;
  const Eigen::MatrixXd solution = A.ldlt().solve(B);  // m x 2
  StabiliserParameters fitted = base;
  if (!solution.allFinite()) return fitted;
  fitted.nonlinear_features = feature_set;
  // The predictor multiplies by focal_px itself; the deltas above already carry it.
  fitted.nonlinear_residual = solution.transpose();
  return fitted;
}

std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds) {
  std::vector<ModelCandidate> candidates;
  candidates.push_back({"physical", fit.parameters.physicalChain()});
  const bool has_linear = fit.parameters.residual.size() != 0;
  if (has_linear) candidates.push_back({"physical + linear residual", fit.parameters});
  // The chain with a better structure (one mechanism or one parameter more each): an integrator
  // held at the end stop (anti-windup), a re-centring that grows with the excursion, both; the
  // stroke in the actuator's axes with their coupling after it; a soft stroke instead of an end
  // stop, alone and with the excursion-dependent re-centring. Each refitted from the chain's
  // parameters.
  if (kinds.structural) {
    StabiliserFitOptions refit_options = options;
    if (kinds.structural_iterations > 0) refit_options.iterations = kinds.structural_iterations;
    for (const auto& [structure, what] :
         {std::pair<StabiliserStructure, std::string>{{true, false, false}, "anti-windup integrator"},
          {{false, true, false}, "excursion-dependent re-centring"},
          {{true, true, false}, "anti-windup integrator + excursion-dependent re-centring"},
          {{false, false, true}, "stroke in the actuator's axes + actuator coupling"},
          {{false, false, false, true}, "soft stroke"},
          {{false, true, false, true}, "soft stroke + excursion-dependent re-centring"}}) {
      try {
        const StabiliserFitResult refit = refitStabiliserStructure(fit.parameters, structure, training, refit_options);
        candidates.push_back(
            {std::string(refit.parameters.residual.size() != 0 ? "physical + linear" : "physical") + ", " + what,
             refit.parameters});
      } catch (const std::invalid_argument&) {
        // No usable lens motion: the simpler candidates stand.
      }
    }
  }
  // Learned dynamics on top of the chain (with its linear bank when it has one), simplest first:
  // a higher-order linear filter of the rate, nonlinear functions of the chain's state, both.
  if (kinds.learned_features) {
    const std::string prefix = has_linear ? "physical + linear + " : "physical + ";
    for (const auto& [set, what] :
         {std::pair<std::string, std::string>{"rate_bank_v1", "learned rate filter"},
          {"excursion_v1", "nonlinear residual"},
          {"excursion_rate_v1", "nonlinear residual + learned rate filter"}}) {
      try {
        candidates.push_back(
            {prefix + what + " (" + set + ")", fitNonlinearResidual(fit.parameters, training, options, set)});
      } catch (const std::invalid_argument&) {
        // No usable lens motion for the residual: the simpler candidates stand.
      }
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
                                     const StabiliserFitOptions& options, double simpler_within,
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
  auto key = [&](const StabiliserCandidate& c) {
    const double v = by_held_out ? c.held_out.rms_px : c.training.rms_px;
    return std::isfinite(v) ? v : std::numeric_limits<double>::infinity();
  };
  std::size_t best = 0;
  for (std::size_t k = 1; k < selection.candidates.size(); ++k)
    if (key(selection.candidates[k]) < key(selection.candidates[best])) best = k;
  // The simplest candidate within simpler_within of the best.
  std::size_t kept = best;
  for (std::size_t k = 0; k < best; ++k) {
    if (key(selection.candidates[k]) <= (1.0 + simpler_within) * key(selection.candidates[best])) {
      kept = k;
      break;
    }
  }
  selection.kept = kept;
  std::ostringstream why;
  why.precision(4);
  why << (by_held_out ? "held-out" : "training (no held-out recordings, so no test of "
                                     "generalisation)")
      << " lens-motion RMS " << key(selection.candidates[kept]) << " px";
  if (kept != best) {
    why << ", within " << 100.0 * simpler_within << " % of the best ('"
        << selection.candidates[best].name << "', " << key(selection.candidates[best])
        << " px) and simpler";
  } else if (selection.candidates.size() > 1) {
    why << ", the lowest of " << selection.candidates.size() << " candidates";
  }
  selection.figures = why.str();
  selection.reason = "kept '" + selection.candidates[kept].name + "': " + selection.figures;
  return selection;
}

}  // namespace deep_ois
