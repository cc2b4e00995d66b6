#include "deep_ois/core/ois/linear_dynamics_basis.h"

#include <Eigen/QR>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;
// More functions than this per axis is no longer a model of a stabiliser (and the alternating
// sums of a long Laguerre chain lose precision).
constexpr int kMaxOrder = 64;

}  // namespace

std::string LinearDynamicsBasisSpec::validate(double step_s) const {
  std::ostringstream why;
  const double nyquist_hz = 0.5 / step_s;
  if (firstOrder()) {
    if (order != static_cast<int>(time_constants_s.size()) || order > kMaxOrder) {
      why << "order: must be the count of time_constants_s, at most " << kMaxOrder << " (got " << order
          << " for " << time_constants_s.size() << ")";
    }
    for (double tau : time_constants_s) {
      if (!(tau > 0.0) || !std::isfinite(tau)) {
        why << "time_constants_s: must be positive and finite (got " << tau << ")";
        break;
      }
    }
    return why.str();
  }
  if (!(pole_hz > 0.0) || !std::isfinite(pole_hz)) {
    why << "pole_hz: must be positive and finite (got " << pole_hz << ")";
  } else if (pole_hz >= nyquist_hz) {
    why << "pole_hz: must be below half the step's rate, " << nyquist_hz << " Hz (got " << pole_hz << ")";
  } else if (order < 1 || order > kMaxOrder) {
    why << "order: must be in [1, " << kMaxOrder << "] (got " << order << ")";
  } else if (!(second_pole_hz >= 0.0) || !std::isfinite(second_pole_hz)) {
    why << "second_pole_hz: must be 0 (none) or positive and finite (got " << second_pole_hz << ")";
  } else if (second_pole_hz >= nyquist_hz) {
    why << "second_pole_hz: must be below half the step's rate, " << nyquist_hz << " Hz (got "
        << second_pole_hz << ")";
  }
  return why.str();
}

double LinearDynamicsBasisSpec::poleRadS(int k) const {
  if (firstOrder()) return 1.0 / time_constants_s[static_cast<std::size_t>(k)];
  const bool second = second_pole_hz > 0.0 && k % 2 == 1;
  return 2.0 * kPi * (second ? second_pole_hz : pole_hz);
}

LinearDynamicsBasis::LinearDynamicsBasis(const LinearDynamicsBasisSpec& spec, double step_s)
    : spec_(spec), step_s_(step_s) {
  if (!(step_s > 0.0) || !std::isfinite(step_s)) {
    throw std::invalid_argument("linear dynamics basis: step_s must be positive and finite");
  }
  const std::string problem = spec.validate(step_s);
  if (!problem.empty()) throw std::invalid_argument("linear dynamics basis: " + problem);
  const int n = spec.order;
  state_ = Eigen::VectorXd::Zero(3 * n);
  next_ = Eigen::VectorXd::Zero(n);
  if (spec.firstOrder()) {
    // Independent leaky integrals: y_k' = u - c_k y_k, c_k = 1 / tau_k, stepped exactly for a held
    // rate as the older residual banks were (the same expressions, so a converted file predicts
    // what it predicted).
    a_ = Eigen::MatrixXd::Zero(n, n);
    ad_ = Eigen::MatrixXd::Zero(n, n);
    b_ = Eigen::VectorXd::Ones(n);
    bd_ = Eigen::VectorXd::Zero(n);
    for (int k = 0; k < n; ++k) {
      const double corner_rad_s = spec.poleRadS(k);
      a_(k, k) = -corner_rad_s;
      ad_(k, k) = std::exp(-corner_rad_s * step_s);
      bd_(k) = -std::expm1(-corner_rad_s * step_s) / corner_rad_s;
    }
    return;
  }
  // x_k' = -p_k x_k + sqrt(2 p_k) v_k, where v_k is what reaches function k through the all-passes
  // (s - p_j) / (s + p_j) before it: v_1 = u, v_{k+1} = v_k - sqrt(2 p_k) x_k.
  a_ = Eigen::MatrixXd::Zero(n, n);
  b_ = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < n; ++k) {
    const double pk = spec.poleRadS(k);
    a_(k, k) = -pk;
    b_(k) = std::sqrt(2.0 * pk);
    for (int j = 0; j < k; ++j) a_(k, j) = -2.0 * std::sqrt(pk * spec.poleRadS(j));
  }
  // Exact for a held input: exp([[A, B], [0, 0]] h) = [[Ad, Bd], [0, 1]].
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(n + 1, n + 1);
  augmented.topLeftCorner(n, n) = a_ * step_s;
  augmented.topRightCorner(n, 1) = b_ * step_s;
  const Eigen::MatrixXd e = augmented.exp();
  ad_ = e.topLeftCorner(n, n);
  bd_ = e.topRightCorner(n, 1);
}

void LinearDynamicsBasis::reset() { state_.setZero(); }

const Eigen::VectorXd& LinearDynamicsBasis::advance(const Eigen::Vector3d& rate_rad_s) {
  const int n = spec_.order;
  for (int axis = 0; axis < 3; ++axis) {
    auto x = state_.segment(axis * n, n);
    // Ad is lower triangular: the product into a scratch vector (kept, so a step allocates
    // nothing) keeps the update exact.
    next_.noalias() = ad_.triangularView<Eigen::Lower>() * x;
    next_ += bd_ * rate_rad_s(axis);
    x = next_;
  }
  return state_;
}

Eigen::MatrixXd linearDynamicsStates(const LinearDynamicsBasisSpec& spec, double step_s,
                                     const std::vector<double>& stamps_s,
                                     const std::vector<Eigen::Vector3d>& rates_rad_s,
                                     const std::vector<double>& times_s) {
  if (stamps_s.size() != rates_rad_s.size()) {
    throw std::invalid_argument("linear dynamics states: " + std::to_string(stamps_s.size()) + " stamps but " +
                                std::to_string(rates_rad_s.size()) + " rates");
  }
  if (stamps_s.size() < 2) throw std::invalid_argument("linear dynamics states: need at least 2 rate samples");
  for (std::size_t i = 0; i < stamps_s.size(); ++i) {
    if (!std::isfinite(stamps_s[i]) || !rates_rad_s[i].allFinite()) {
      throw std::invalid_argument("linear dynamics states: rate sample " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(stamps_s[i] > stamps_s[i - 1])) {
      throw std::invalid_argument("linear dynamics states: stamps must increase (sample " + std::to_string(i) +
                                  " is not after the one before)");
    }
  }
  for (std::size_t i = 0; i < times_s.size(); ++i) {
    if (!std::isfinite(times_s[i])) {
      throw std::invalid_argument("linear dynamics states: query time " + std::to_string(i) + " is not finite");
    }
  }
  LinearDynamicsBasis basis(spec, step_s);
  // The state after step j, at stamps_s[0] + j * step_s (j = 0: at rest).
  const double start = stamps_s.front();
  const long steps = static_cast<long>(std::floor((stamps_s.back() - start) / step_s + 1e-9));
  Eigen::MatrixXd grid(steps + 1, basis.size());
  grid.row(0) = basis.state().transpose();
  std::size_t i = 0;
  for (long j = 0; j < steps; ++j) {
    const double middle = start + (static_cast<double>(j) + 0.5) * step_s;
    while (i + 2 < stamps_s.size() && stamps_s[i + 1] <= middle) ++i;
    const double alpha = std::clamp((middle - stamps_s[i]) / (stamps_s[i + 1] - stamps_s[i]), 0.0, 1.0);
    grid.row(j + 1) = basis.advance((1.0 - alpha) * rates_rad_s[i] + alpha * rates_rad_s[i + 1]).transpose();
  }
  Eigen::MatrixXd out(static_cast<long>(times_s.size()), basis.size());
  for (std::size_t q = 0; q < times_s.size(); ++q) {
    const double position = std::clamp((times_s[q] - start) / step_s, 0.0, static_cast<double>(steps));
    const long below = std::min(static_cast<long>(std::floor(position)), std::max(0L, steps - 1));
    const double fraction = steps > 0 ? position - static_cast<double>(below) : 0.0;
    out.row(static_cast<long>(q)) =
        steps > 0 ? ((1.0 - fraction) * grid.row(below) + fraction * grid.row(below + 1)).eval() : grid.row(0);
  }
  return out;
}

Eigen::MatrixXd fitLinearDynamicsCoefficients(const Eigen::MatrixXd& states, const Eigen::MatrixXd& targets,
                                              const Eigen::VectorXd& weights, double ridge,
                                              LinearDynamicsFitReport* report) {
  const long rows = states.rows(), size = states.cols();
  auto fail = [](const std::string& why) { throw std::invalid_argument("linear dynamics fit: " + why); };
  if (size == 0) fail("the states have no columns");
  if (targets.cols() != 2) fail("targets must have 2 columns (lens x, y), got " + std::to_string(targets.cols()));
  if (targets.rows() != rows) {
    fail(std::to_string(rows) + " state rows but " + std::to_string(targets.rows()) + " target rows");
  }
  if (weights.size() != 0 && weights.size() != rows) {
    fail(std::to_string(rows) + " rows but " + std::to_string(weights.size()) + " weights");
  }
  if (!(ridge >= 0.0) || !std::isfinite(ridge)) fail("ridge must be non-negative and finite (got " + std::to_string(ridge) + ")");
  for (long i = 0; i < rows; ++i) {
    if (!states.row(i).allFinite()) fail("state row " + std::to_string(i) + " is not finite");
    if (!targets.row(i).allFinite()) fail("target row " + std::to_string(i) + " is not finite");
    if (weights.size() != 0 && (!(weights(i) >= 0.0) || !std::isfinite(weights(i)))) {
      fail("weight " + std::to_string(i) + " must be non-negative and finite (got " + std::to_string(weights(i)) + ")");
    }
  }
  const Eigen::VectorXd w = weights.size() != 0 ? weights : Eigen::VectorXd::Ones(rows);
  const Eigen::VectorXd root_w = w.cwiseSqrt();
  int samples = 0;
  for (long i = 0; i < rows; ++i) samples += w(i) > 0.0 ? 1 : 0;
  // Per component: its weighted energy G_jj; components without any are left out (coefficient 0).
  const Eigen::VectorXd energy = (states.array().square().colwise() * w.array()).colwise().sum().transpose();
  std::vector<long> excited;
  for (long j = 0; j < size; ++j)
    if (energy(j) > 0.0) excited.push_back(j);
  const long m = static_cast<long>(excited.size());
  if (m == 0) fail("no state component has weighted energy (all weights 0, or the rate never moved)");
  if (samples < m) {
    fail(std::to_string(samples) + " weighted samples for " + std::to_string(m) + " excited state components");
  }
  // Scaled to unit energy per component (z_j = x_j / sqrt(G_jj)), the ridge is ridge * |D|^2 for
  // the scaled coefficients D: stack sqrt(w) Z over sqrt(ridge) I and solve by QR.
  const long extra = ridge > 0.0 ? m : 0;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(rows + extra, m);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(rows + extra, 2);
  Eigen::VectorXd scale(m);
  for (long c = 0; c < m; ++c) {
    scale(c) = 1.0 / std::sqrt(energy(excited[static_cast<std::size_t>(c)]));
    a.col(c).head(rows) = root_w.cwiseProduct(states.col(excited[static_cast<std::size_t>(c)])) * scale(c);
  }
  b.topRows(rows) = targets.array().colwise() * root_w.array();
  if (extra > 0) a.bottomRows(m).diagonal().setConstant(std::sqrt(ridge));
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (ridge == 0.0 && qr.rank() < m) {
    fail("the states are rank-deficient (rank " + std::to_string(qr.rank()) + " of " + std::to_string(m) +
         "): use a positive ridge or a lower order");
  }
  const Eigen::MatrixXd scaled = qr.solve(b);  // m x 2
  Eigen::MatrixXd coefficients = Eigen::MatrixXd::Zero(2, size);
  for (long c = 0; c < m; ++c)
    coefficients.col(excited[static_cast<std::size_t>(c)]) = scaled.row(c).transpose() * scale(c);
  if (report) {
    report->samples = samples;
    report->unexcited_states = static_cast<int>(size - m);
    const double total_w = w.sum();
    const Eigen::MatrixXd residual = targets - states * coefficients.transpose();
    const double sum = (residual.array().square().colwise() * w.array()).sum();
    report->weighted_rms = total_w > 0.0 ? std::sqrt(sum / (2.0 * total_w)) : 0.0;
  }
  return coefficients;
}

}  // namespace deep_ois
