#include "deep_ois/core/ois/linear_dynamics_rls.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"

namespace deep_ois {

std::string LinearDynamicsRlsOptions::validate() const {
  std::ostringstream why;
  if (!(forgetting_per_s > 0.0 && forgetting_per_s <= 1.0))
    why << "forgetting_per_s must be in (0, 1] (got " << forgetting_per_s << ")";
  else if (!(prior_lens_motions > 0.0) || !std::isfinite(prior_lens_motions))
    why << "prior_lens_motions must be positive and finite (got " << prior_lens_motions << ")";
  else if (!(huber_px > 0.0) || !std::isfinite(huber_px))
    why << "huber_px must be positive and finite (got " << huber_px << ")";
  return why.str();
}

LinearDynamicsRls::LinearDynamicsRls(const Eigen::MatrixXd& coefficients, const LinearDynamicsRlsOptions& options)
    : options_(options), coefficients_(coefficients) {
  if (const std::string problem = options.validate(); !problem.empty())
    throw std::invalid_argument("linear dynamics RLS: " + problem);
  if (coefficients.rows() != 2 || coefficients.cols() < 1 || !coefficients.allFinite())
    throw std::invalid_argument("linear dynamics RLS: the coefficients must be a finite 2 x n matrix (got " +
                                std::to_string(coefficients.rows()) + " x " + std::to_string(coefficients.cols()) +
                                ")");
}

void LinearDynamicsRls::start(const LinearDynamicsEvidence& evidence) {
  const long n = coefficients_.cols();
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::MatrixXd& along = axis == 0 ? evidence.along_x : evidence.along_y;
    Eigen::VectorXd energy = Eigen::VectorXd::Zero(n);
    double weight = 0.0;
    for (long i = 0; i < evidence.rows(); ++i) {
      const double w = evidence.weights(i);
      if (!(w > 0.0) || !along.row(i).allFinite()) continue;
      energy += w * along.row(i).transpose().cwiseAbs2();
      weight += w;
    }
    // A column the first evidence never excites gets the mean of the others' energy (so its prior
    // is as strong, in the same units), or 1 when none moved.
    const double mean = weight > 0.0 ? energy.sum() / (weight * static_cast<double>(n)) : 0.0;
    Eigen::VectorXd information(n);
    for (long j = 0; j < n; ++j) {
      const double per_motion = weight > 0.0 ? energy(j) / weight : 0.0;
      information(j) = options_.prior_lens_motions * (per_motion > 1e-12 * mean && per_motion > 0.0 ? per_motion
                                                                                   : mean > 0.0 ? mean : 1.0);
    }
    p_[axis] = information.cwiseInverse().asDiagonal();
    p0_trace_[axis] = p_[axis].trace();
  }
  started_ = true;
}

void LinearDynamicsRls::add(const LinearDynamicsEvidence& evidence) {
  const long n = coefficients_.cols();
  const long m = evidence.rows();
  if (evidence.along_x.cols() != n || evidence.along_y.cols() != n || evidence.along_x.rows() != m ||
      evidence.along_y.rows() != m || evidence.targets.cols() != 2 || evidence.weights.size() != m ||
      evidence.residual_px.size() != m || evidence.stamps_s.size() != m)
    throw std::invalid_argument("linear dynamics RLS: the evidence must have " + std::to_string(n) +
                                " columns (the coefficients') and one row per lens motion in every part");
  if (m == 0) return;
  if (!started_) {
    start(evidence);
    last_stamp_s_ = evidence.stamps_s.minCoeff();
  }
  std::vector<long> order(static_cast<std::size_t>(m));
  std::iota(order.begin(), order.end(), 0L);
  std::stable_sort(order.begin(), order.end(),
                   [&](long a, long b) { return evidence.stamps_s(a) < evidence.stamps_s(b); });
  const double log_forgetting = std::log(options_.forgetting_per_s);
  const RobustLoss huber = RobustLoss::huber(options_.huber_px);  // the solver's loss
  Eigen::VectorXd gain(n);
  for (const long i : order) {
    const double w = evidence.weights(i);
    if (!(w > 0.0) || !std::isfinite(w) || !evidence.along_x.row(i).allFinite() ||
        !evidence.along_y.row(i).allFinite() || !evidence.targets.row(i).allFinite() ||
        !std::isfinite(evidence.stamps_s(i))) {
      ++skipped_;
      continue;
    }
    // Forgetting over the time since the last row, never past the prior's uncertainty (a stream
    // that stops exciting some direction must not blow its variance up).
    const double dt = std::max(0.0, evidence.stamps_s(i) - last_stamp_s_);
    last_stamp_s_ = std::max(last_stamp_s_, evidence.stamps_s(i));
    const double grow = std::exp(-log_forgetting * dt);
    // The residual of this row with the current coefficients: its Huber weight.
    Eigen::Vector2d residual;
    residual(0) = evidence.targets(i, 0) - evidence.along_x.row(i).dot(coefficients_.row(0));
    residual(1) = evidence.targets(i, 1) - evidence.along_y.row(i).dot(coefficients_.row(1));
    const double robust = w * huber.weight(residual.squaredNorm());
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::MatrixXd& p = p_[axis];
      if (grow > 1.0 && p.trace() * grow <= p0_trace_[axis]) p *= grow;
      const auto phi = (axis == 0 ? evidence.along_x : evidence.along_y).row(i).transpose();
      gain.noalias() = p * phi;
      const double denominator = 1.0 / robust + phi.dot(gain);
      if (!(denominator > 0.0) || !std::isfinite(denominator)) continue;
      coefficients_.row(axis) += (residual(axis) / denominator) * gain.transpose();
      p.noalias() -= (gain / denominator) * gain.transpose();
      p = 0.5 * (p + p.transpose()).eval();  // symmetric against rounding
    }
    ++samples_;
  }
}

void LinearDynamicsRls::rebase(const Eigen::MatrixXd& coefficients) {
  if (coefficients.rows() != coefficients_.rows() || coefficients.cols() != coefficients_.cols() ||
      !coefficients.allFinite())
    throw std::invalid_argument("linear dynamics RLS: rebase needs a finite 2 x " +
                                std::to_string(coefficients_.cols()) + " matrix");
  coefficients_ = coefficients;
}

}  // namespace deep_ois
