#include "deep_ois/core/ois/lens_dynamics_adaptation.h"
#include "deep_ois/core/ois/stages/learned_lens_dynamics.h"

#include "deep_ois/core/common/nonlinear_least_squares.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace deep_ois {
namespace {

// The predicted and observed lens motions of every usable observation, stacked (x, y per
// observation), with the observations' weights.
struct Predictions {
  Eigen::VectorXd predicted, observed, weight;
};

Predictions predictAll(const StabiliserModel& parameters,
                       const std::vector<StabiliserFitRecording>& recordings,
                       const StabiliserFitOptions& options) {
  std::vector<double> predicted, observed, weight;
  for (const StabiliserFitRecording& recording : recordings) {
    const std::vector<Eigen::Vector2d> motion =
        predictLensMotion(parameters, recording, options.step_s, options.warm_up_s);
    for (std::size_t i = 0; i < motion.size(); ++i) {
      if (!motion[i].allFinite()) continue;
      const LensMotionObservation& o = recording.observations[i];
      for (int k = 0; k < 2; ++k) {
        predicted.push_back(motion[i](k));
        observed.push_back(o.motion_px(k));
        weight.push_back(o.weight);
      }
    }
  }
  Predictions p;
  p.predicted = Eigen::Map<Eigen::VectorXd>(predicted.data(), static_cast<long>(predicted.size()));
  p.observed = Eigen::Map<Eigen::VectorXd>(observed.data(), static_cast<long>(observed.size()));
  p.weight = Eigen::Map<Eigen::VectorXd>(weight.data(), static_cast<long>(weight.size()));
  return p;
}

constexpr double kInfinity = std::numeric_limits<double>::infinity();

double rms(const Eigen::VectorXd& error, const Eigen::VectorXd& weight) {
  const double total = weight.sum() / 2.0;
  return total > 0.0 ? std::sqrt(error.cwiseAbs2().cwiseProduct(weight).sum() / total) : 0.0;
}

}  // namespace

StabiliserModel genericLensDynamicsModel(std::shared_ptr<const LensDynamicsNetwork> network) {
  if (!network) throw std::invalid_argument("lens dynamics: no network");
  StabiliserModel parameters = noLensMotion();
  LearnedLensDynamics& learned = parameters.get<LearnedLensDynamics>();
  learned.network = network;
  learned.conditioning = network->default_conditioning;
  return parameters;
}

LensDynamicsAdaptation adaptLensDynamics(std::shared_ptr<const LensDynamicsNetwork> network,
                                         const std::vector<StabiliserFitRecording>& recordings,
                                         const StabiliserFitOptions& fit_options,
                                         const LensDynamicsAdaptationOptions& options) {
  StabiliserModel parameters = genericLensDynamicsModel(network);
  const std::string problem = parameters.validate();
  if (!problem.empty()) throw std::invalid_argument("lens dynamics adaptation: " + problem);
  const long c_size = network->conditioning_size;
  const long map_size = options.fit_output_map ? 4 : 0;
  const Eigen::VectorXd& mean = network->default_conditioning;
  const Eigen::VectorXd& spread = network->conditioning_spread;
  LensDynamicsAdaptation result;

  // The network's lens motions with the map at the identity (the map applies after: linear).
  auto unmapped = [&](const Eigen::VectorXd& conditioning) {
    StabiliserModel p = parameters;
    p.get<LearnedLensDynamics>().conditioning = conditioning;
    p.get<LearnedLensDynamics>().output_map.setIdentity();
    ++result.passes;
    return predictAll(p, recordings, fit_options);
  };
  auto applyMap = [](const Eigen::Matrix2d& map, const Eigen::VectorXd& motion) {
    Eigen::VectorXd out(motion.size());
    for (long i = 0; i + 1 < motion.size(); i += 2)
      out.segment<2>(i) = map * Eigen::Vector2d(motion(i), motion(i + 1));
    return out;
  };
  Predictions base = unmapped(mean);
  if (base.predicted.size() == 0)
    throw std::invalid_argument(
        "lens dynamics adaptation: no usable lens motion (every observation is before the model's "
        "warm-up or outside the gyro stream)");
  result.observations_used = static_cast<std::size_t>(base.predicted.size() / 2);
  result.rms_start_px = rms(base.predicted - base.observed, base.weight);

  // The solver's problem: the conditioning (pulled towards the designs' distribution by prior
  // rows sqrt(prior_weight) (c - mean) / spread, outside the loss) and the map's four entries
  // (row-major); residuals sqrt(weight) (map * motion - observed) per observation, Huber loss.
  const long n = base.predicted.size(), m = c_size + map_size;
  const Eigen::VectorXd sqrt_weight = base.weight.cwiseMax(0.0).cwiseSqrt();
  const double sqrt_prior = std::sqrt(options.prior_weight_px2);
  auto mapOf = [&](const Eigen::VectorXd& v) {
    Eigen::Matrix2d map = Eigen::Matrix2d::Identity();
    if (map_size) map = Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(v.data() + c_size);
    return map;
  };
  auto residualsAt = [&](const Predictions& p, const Eigen::VectorXd& v, Eigen::VectorXd* r) {
    r->resize(n + c_size);
    r->head(n) = sqrt_weight.cwiseProduct(applyMap(mapOf(v), p.predicted) - base.observed);
    r->tail(c_size) = sqrt_prior * (v.head(c_size) - mean).cwiseQuotient(spread);
  };
  NonlinearLeastSquaresProblem fit;
  for (long k = 0; k < c_size; ++k)
    fit.parameters.push_back({"conditioning_" + std::to_string(k), -kInfinity, kInfinity, false,
                                  options.difference_step * spread(k)});
  for (long k = 0; k < map_size; ++k)
    fit.parameters.push_back({"output_map_" + std::to_string(k / 2) + std::to_string(k % 2)});
  fit.block_size = 2;
  fit.robust_residual_count = n;
  fit.residuals = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) {
    const Predictions p = unmapped(v.head(c_size));
    if (p.predicted.size() != n) return false;  // the usable observations changed: refused
    residualsAt(p, v, r);
    return true;
  };
  // Derivatives by forward differences over the conditioning (one pass each), in closed form
  // over the map (the lens is linear in it).
  fit.residuals_and_jacobian = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r, Eigen::MatrixXd* J) {
    const Predictions p = unmapped(v.head(c_size));
    if (p.predicted.size() != n) return false;
    residualsAt(p, v, r);
    const Eigen::Matrix2d map = mapOf(v);
    const Eigen::VectorXd mapped = applyMap(map, p.predicted);
    J->setZero(n + c_size, m);
    for (long k = 0; k < c_size; ++k) {
      Eigen::VectorXd shifted = v.head(c_size);
      const double h = options.difference_step * spread(k);
      shifted(k) += h;
      const Predictions moved = unmapped(shifted);
      if (moved.predicted.size() != n) return false;
      J->col(k).head(n) = sqrt_weight.cwiseProduct(applyMap(map, moved.predicted) - mapped) / h;
      (*J)(n + k, k) = sqrt_prior / spread(k);
    }
    for (long k = 0; k < map_size; ++k) {
      const int row = static_cast<int>(k / 2), col = static_cast<int>(k % 2);
      for (long i = 0; i + 1 < n; i += 2) (*J)(i + row, c_size + k) = sqrt_weight(i + row) * p.predicted(i + col);
    }
    return true;
  };
  Eigen::VectorXd start(m);
  start.head(c_size) = mean;
  if (map_size) start.tail(map_size) << 1.0, 0.0, 0.0, 1.0;
  NonlinearLeastSquaresOptions solver;
  solver.loss = RobustLoss::huber(fit_options.huber_px);
  solver.engine = fit_options.solver_engine;
  solver.max_iterations = options.iterations;
  solver.function_tolerance = 1e-4;
  // Lighter damping than the chain's, raised more gently: the conditioning is near its prior's
  // mean, where Gauss-Newton steps are good.
  solver.damping = {1e-3, 3.0, 4.0, 1e-7, 6};
  const NonlinearLeastSquaresReport report = solveNonlinearLeastSquares(fit, start, solver);
  result.rms_history = report.rms_history;
  const Eigen::VectorXd solved = report.usable() ? report.values : start;
  const Eigen::VectorXd c = solved.head(c_size);
  const Eigen::Matrix2d map = mapOf(solved);
  base = unmapped(c);
  const Eigen::VectorXd error = applyMap(map, base.predicted) - base.observed;
  parameters.get<LearnedLensDynamics>().conditioning = c;
  parameters.get<LearnedLensDynamics>().output_map = map;
  result.parameters = parameters;
  result.rms_px = rms(error, base.weight);
  return result;
}

StabiliserModel refitLensDynamicsOutput(const StabiliserModel& adapted,
                                             const std::vector<StabiliserFitRecording>& recordings,
                                             const StabiliserFitOptions& options, double ridge) {
  const std::string problem = adapted.validate();
  if (!problem.empty()) throw std::invalid_argument("lens dynamics output refit: " + problem);
  if (!adapted.get<LearnedLensDynamics>().active())
    throw std::invalid_argument("lens dynamics output refit: the model has no learned stage");
  const LearnedLensDynamics& learned = adapted.get<LearnedLensDynamics>();
  const LensDynamicsNetwork& net = *learned.network;
  const bool skip = net.w_skip.size() != 0;
  const long hidden = net.hidden_size;
  const long h = hidden + (skip ? net.inputSize() : 0);  // what the layer reads
  // The layer as the model applies it now: lens = output_scale * (W0 state + b0), focal units.
  Eigen::MatrixXd w0(2, h);
  w0.leftCols(hidden) = learned.output_map * net.w_output;
  if (skip) w0.rightCols(net.inputSize()) = learned.output_map * net.w_skip;
  // Huber weights from the current layer's residuals; the package's ridge convention, per state
  // component relative to its energy, towards the current layer.
  RobustRidgeRegression regression(h, 2, RobustLoss::huber(options.huber_px));
  for (const StabiliserFitRecording& recording : recordings) {
    const double scale = recording.focal_px * net.output_scale;
    visitCoveredObservations(
        adapted, recording, options.step_s, options.warm_up_s,
        [&](const LensShiftPredictor& predictor, std::size_t index) {
          const LensMotionObservation& o = recording.observations[index];
          const Eigen::VectorXd delta =
              scale * (predictor.learnedStateAt(o.t_b_s) - predictor.learnedStateAt(o.t_a_s));
          // What the model predicts without its learned stage's motion (the chain, if any), and
          // what the learned stage must then explain.
          const Eigen::Vector2d learned_motion = w0 * delta;
          const Eigen::Vector2d others =
              predictor.lensShiftAt(o.t_b_s) - predictor.lensShiftAt(o.t_a_s) - learned_motion;
          const Eigen::Vector2d target = o.motion_px - others;
          regression.add(delta, target, o.weight, (target - learned_motion).norm());
        },
        [](LensShiftPredictor& predictor) { predictor.recordLearnedState(); });
  }
  if (regression.count() == 0) throw std::invalid_argument("lens dynamics output refit: no usable lens motion");
  const Eigen::MatrixXd prior = w0.transpose();
  Eigen::MatrixXd solution;  // H x 2
  StabiliserModel refitted = adapted;
  if (!regression.solve(ridge, &solution, &prior)) return refitted;
  auto network = std::make_shared<LensDynamicsNetwork>(net);
  network->w_output = solution.topRows(hidden).transpose();
  if (skip) network->w_skip = solution.bottomRows(net.inputSize()).transpose();
  network->b_output = learned.output_map * net.b_output;
  refitted.get<LearnedLensDynamics>().network = network;
  refitted.get<LearnedLensDynamics>().output_map.setIdentity();
  return refitted;
}

}  // namespace deep_ois
