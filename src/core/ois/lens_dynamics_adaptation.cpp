#include "deep_ois/core/ois/lens_dynamics_adaptation.h"
#include "deep_ois/core/ois/stages/learned_lens_dynamics.h"

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

// Huber weights per observation (both components share their norm's weight).
Eigen::VectorXd huberWeights(const Eigen::VectorXd& error, const Eigen::VectorXd& weight, double huber_px) {
  Eigen::VectorXd w(error.size());
  for (long i = 0; i + 1 < error.size(); i += 2) {
    const double norm = std::hypot(error(i), error(i + 1));
    const double h = norm <= huber_px ? 1.0 : huber_px / norm;
    w(i) = w(i + 1) = h * weight(i);
  }
  return w;
}

double huberCost(const Eigen::VectorXd& error, const Eigen::VectorXd& weight, double huber_px) {
  double cost = 0.0;
  for (long i = 0; i + 1 < error.size(); i += 2) {
    const double norm = std::hypot(error(i), error(i + 1));
    cost += weight(i) * (norm <= huber_px ? norm * norm : 2.0 * huber_px * norm - huber_px * huber_px);
  }
  return cost;
}

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
  auto priorCost = [&](const Eigen::VectorXd& c) {
    return options.prior_weight_px2 * (c - mean).cwiseQuotient(spread).squaredNorm();
  };

  Eigen::VectorXd c = mean;
  Eigen::Matrix2d map = Eigen::Matrix2d::Identity();
  Predictions base = unmapped(c);
  if (base.predicted.size() == 0)
    throw std::invalid_argument(
        "lens dynamics adaptation: no usable lens motion (every observation is before the model's "
        "warm-up or outside the gyro stream)");
  result.observations_used = static_cast<std::size_t>(base.predicted.size() / 2);
  Eigen::VectorXd error = applyMap(map, base.predicted) - base.observed;
  double cost = huberCost(error, base.weight, fit_options.huber_px) + priorCost(c);
  result.rms_start_px = rms(error, base.weight);
  double lambda = 1e-3;
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    // Jacobian of the motions: conditioning by forward differences, map in closed form.
    const long n = error.size(), m = c_size + map_size;
    Eigen::MatrixXd J(n, m);
    for (long k = 0; k < c_size; ++k) {
      Eigen::VectorXd shifted = c;
      const double h = options.difference_step * spread(k);
      shifted(k) += h;
      const Predictions moved = unmapped(shifted);
      if (moved.predicted.size() != n)
        throw std::logic_error("lens dynamics adaptation: the usable observations changed");
      J.col(k) = (applyMap(map, moved.predicted) - applyMap(map, base.predicted)) / h;
    }
    for (long k = 0; k < map_size; ++k) {
      const int row = static_cast<int>(k / 2), col = static_cast<int>(k % 2);
      J.col(c_size + k).setZero();
      for (long i = 0; i + 1 < n; i += 2) J(i + row, c_size + k) = base.predicted(i + col);
    }
    const Eigen::VectorXd w = huberWeights(error, base.weight, fit_options.huber_px);
    Eigen::MatrixXd A = J.transpose() * w.asDiagonal() * J;
    Eigen::VectorXd g = J.transpose() * w.cwiseProduct(error);
    // The prior on the conditioning: prior_weight * ((c - mean) / spread)^2.
    for (long k = 0; k < c_size; ++k) {
      const double s2 = spread(k) * spread(k);
      A(k, k) += options.prior_weight_px2 / s2;
      g(k) += options.prior_weight_px2 * (c(k) - mean(k)) / s2;
    }
    bool accepted = false;
    for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
      Eigen::MatrixXd damped = A;
      damped.diagonal() += lambda * (A.diagonal().array() + 1e-12).matrix();
      const Eigen::VectorXd delta = -damped.ldlt().solve(g);
      if (!delta.allFinite()) break;
      const Eigen::VectorXd c_new = c + delta.head(c_size);
      Eigen::Matrix2d map_new = map;
      if (map_size) map_new += Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(delta.data() + c_size);
      const Predictions trial = unmapped(c_new);
      if (trial.predicted.size() != n) {
        lambda *= 4.0;
        continue;
      }
      const Eigen::VectorXd trial_error = applyMap(map_new, trial.predicted) - trial.observed;
      const double trial_cost = huberCost(trial_error, trial.weight, fit_options.huber_px) + priorCost(c_new);
      if (trial_cost < cost) {
        const double relative = (cost - trial_cost) / std::max(cost, 1e-12);
        c = c_new;
        map = map_new;
        base = trial;
        error = trial_error;
        cost = trial_cost;
        lambda = std::max(lambda / 3.0, 1e-7);
        accepted = true;
        result.rms_history.push_back(rms(error, base.weight));
        if (relative < 1e-4) iteration = options.iterations;  // converged
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) break;
  }
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
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(h, h);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(h, 2);
  std::size_t used = 0;
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
          const double norm = (target - learned_motion).norm();
          const double w =
              std::max(0.0, o.weight) * (norm <= options.huber_px ? 1.0 : options.huber_px / norm);
          A.noalias() += w * delta * delta.transpose();
          B.noalias() += w * delta * target.transpose();
          ++used;
        },
        [](LensShiftPredictor& predictor) { predictor.recordLearnedState(); });
  }
  if (used == 0) throw std::invalid_argument("lens dynamics output refit: no usable lens motion");
  // Ridge per state component, relative to its energy, towards the current layer.
  const double floor = 1e-12 * std::max(1e-300, A.diagonal().maxCoeff());
  Eigen::VectorXd penalty(h);
  for (long k = 0; k < h; ++k) penalty(k) = ridge * A(k, k) + floor;
  A.diagonal() += penalty;
  B += penalty.asDiagonal() * w0.transpose();
  const Eigen::MatrixXd solution = A.ldlt().solve(B);  // H x 2
  StabiliserModel refitted = adapted;
  if (!solution.allFinite()) return refitted;
  auto network = std::make_shared<LensDynamicsNetwork>(net);
  network->w_output = solution.topRows(hidden).transpose();
  if (skip) network->w_skip = solution.bottomRows(net.inputSize()).transpose();
  network->b_output = learned.output_map * net.b_output;
  refitted.get<LearnedLensDynamics>().network = network;
  refitted.get<LearnedLensDynamics>().output_map.setIdentity();
  return refitted;
}

}  // namespace deep_ois
