// The recursive least squares on the linear-dynamics stage's coefficients
// (core/ois/linear_dynamics_rls.h) on streamed rows of a known linear response: without forgetting
// it is the exact ridge least squares of every row (towards its start), it recovers the response,
// and with forgetting it follows a change of the response that the one without cannot.
// (Its evidence from a real chain: test_linear_dynamics_stage.cpp.)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <stdexcept>

#include "deep_ois/core/ois/linear_dynamics_rls.h"

namespace deep_ois {
namespace {

constexpr long kColumns = 6;
constexpr double kRowsPerSecond = 180.0;  // 30 frame pairs a second, 6 row patches each

Eigen::MatrixXd response(double scale) {
  Eigen::MatrixXd c(2, kColumns);
  for (long j = 0; j < kColumns; ++j) {
    c(0, j) = scale * std::sin(1.3 * j + 0.2);
    c(1, j) = scale * std::cos(0.7 * j + 0.9);
  }
  return c;
}

// `seconds` of rows from `truth` (regressors of a few pixels per unit, as the stage's), noise
// `noise_px`, stamps from `start_s`.
LinearDynamicsEvidence stream(const Eigen::MatrixXd& truth, double seconds, double start_s, double noise_px,
                              unsigned seed) {
  const long m = static_cast<long>(seconds * kRowsPerSecond);
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  LinearDynamicsEvidence e;
  e.along_x.resize(m, kColumns);
  e.along_y.resize(m, kColumns);
  e.targets.resize(m, 2);
  e.weights = Eigen::VectorXd::Ones(m);
  e.residual_px = Eigen::VectorXd::Zero(m);
  e.stamps_s.resize(m);
  for (long i = 0; i < m; ++i) {
    for (long j = 0; j < kColumns; ++j) {
      e.along_x(i, j) = 4.0 * unit(rng) / (1.0 + j);  // columns of unequal energy, as a basis' are
      e.along_y(i, j) = e.along_x(i, j) + 0.5 * unit(rng);
    }
    e.targets(i, 0) = e.along_x.row(i).dot(truth.row(0)) + noise_px * unit(rng);
    e.targets(i, 1) = e.along_y.row(i).dot(truth.row(1)) + noise_px * unit(rng);
    e.stamps_s(i) = start_s + static_cast<double>(i) / kRowsPerSecond;
  }
  return e;
}

// Row blocks of `e` as windows of 2 s, fed one by one (as the learner feeds its windows).
void feedInWindows(LinearDynamicsRls& rls, const LinearDynamicsEvidence& e) {
  const long per_window = static_cast<long>(2.0 * kRowsPerSecond);
  for (long first = 0; first < e.rows(); first += per_window) {
    const long count = std::min(per_window, e.rows() - first);
    LinearDynamicsEvidence window;
    window.along_x = e.along_x.middleRows(first, count);
    window.along_y = e.along_y.middleRows(first, count);
    window.targets = e.targets.middleRows(first, count);
    window.weights = e.weights.segment(first, count);
    window.residual_px = e.residual_px.segment(first, count);
    window.stamps_s = e.stamps_s.segment(first, count);
    rls.add(window);
  }
}

double relativeError(const Eigen::MatrixXd& estimate, const Eigen::MatrixXd& truth) {
  return (estimate - truth).norm() / truth.norm();
}

TEST(LinearDynamicsRls, WithoutForgettingItIsTheRidgeLeastSquaresOfEveryRow) {
  LinearDynamicsRlsOptions options;
  options.forgetting_per_s = 1.0;
  options.huber_px = 1e9;  // no robust weights: the plain least squares
  const Eigen::MatrixXd start = response(0.05);
  const LinearDynamicsEvidence e = stream(response(0.2), 10.0, 0.0, 0.1, 1);
  LinearDynamicsRls rls(start, options);
  feedInWindows(rls, e);
  EXPECT_EQ(rls.samples(), static_cast<std::size_t>(e.rows()));
  // The closed form: (P0^-1 + A^T A) c = P0^-1 c0 + A^T y, P0^-1 = prior x each column's mean energy
  // in the first window (2 s of rows).
  const long first = static_cast<long>(2.0 * kRowsPerSecond);
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::MatrixXd& a = axis == 0 ? e.along_x : e.along_y;
    const Eigen::VectorXd prior =
        options.prior_lens_motions * a.topRows(first).cwiseAbs2().colwise().sum().transpose() / first;
    const Eigen::MatrixXd normal = Eigen::MatrixXd(prior.asDiagonal()) + a.transpose() * a;
    const Eigen::VectorXd rhs = prior.cwiseProduct(start.row(axis).transpose()) + a.transpose() * e.targets.col(axis);
    const Eigen::VectorXd exact = normal.ldlt().solve(rhs);
    EXPECT_LT((rls.coefficients().row(axis).transpose() - exact).norm(), 1e-8 * exact.norm()) << "axis " << axis;
    EXPECT_LT((rls.covariance(axis) - Eigen::MatrixXd(normal.inverse())).norm(), 1e-8 * normal.inverse().norm());
  }
}

TEST(LinearDynamicsRls, RecoversAKnownLinearResponseFromStreamedRows) {
  const Eigen::MatrixXd truth = response(0.2);
  LinearDynamicsRls rls(Eigen::MatrixXd::Zero(2, kColumns), LinearDynamicsRlsOptions());
  feedInWindows(rls, stream(truth, 20.0, 0.0, 0.1, 2));
  // From an all-wrong start (zero, weighted as 20 rows) through Huber weights (the first rows' residual
  // is several times the threshold): within 3 % of the truth after 20 s of rows.
  EXPECT_LT(relativeError(rls.coefficients(), truth), 0.03) << rls.coefficients();
}

TEST(LinearDynamicsRls, OutliersDoNotPullItAway) {
  // A tenth of the rows 20 px off (a track that was a moving object): the Huber weights keep the
  // estimate near the truth, where the plain least squares is pulled away.
  const Eigen::MatrixXd truth = response(0.2);
  LinearDynamicsEvidence e = stream(truth, 20.0, 0.0, 0.1, 3);
  for (long i = 0; i < e.rows(); i += 10) e.targets(i, 0) += 20.0;
  LinearDynamicsRlsOptions plain;
  plain.huber_px = 1e9;
  LinearDynamicsRls robust(Eigen::MatrixXd::Zero(2, kColumns), LinearDynamicsRlsOptions());
  LinearDynamicsRls squares(Eigen::MatrixXd::Zero(2, kColumns), plain);
  feedInWindows(robust, e);
  feedInWindows(squares, e);
  EXPECT_LT(relativeError(robust.coefficients(), truth), 0.5 * relativeError(squares.coefficients(), truth));
}

TEST(LinearDynamicsRls, ForgettingTracksAChangeOfTheResponse) {
  // 30 s of one response, then 20 s of another (the stabiliser changed): with a memory of ~5 s the
  // estimate follows the new one; without forgetting it stays between the two.
  const Eigen::MatrixXd before = response(0.2), after = response(0.2) + 0.6 * response(0.2).rowwise().reverse();
  LinearDynamicsRlsOptions forgetting;
  forgetting.forgetting_per_s = 0.8;
  LinearDynamicsRlsOptions remembering;
  remembering.forgetting_per_s = 1.0;
  LinearDynamicsRls tracking(Eigen::MatrixXd::Zero(2, kColumns), forgetting);
  LinearDynamicsRls fixed(Eigen::MatrixXd::Zero(2, kColumns), remembering);
  for (LinearDynamicsRls* rls : {&tracking, &fixed}) {
    feedInWindows(*rls, stream(before, 30.0, 0.0, 0.1, 4));
    feedInWindows(*rls, stream(after, 20.0, 30.0, 0.1, 5));
  }
  const double change = (after - before).norm();
  EXPECT_LT((tracking.coefficients() - after).norm(), 0.05 * change) << tracking.coefficients();
  EXPECT_GT((fixed.coefficients() - after).norm(), 0.3 * change) << fixed.coefficients();
  // The forgetting never makes it less certain than its prior: a stream that stops leaves P bounded.
  for (int axis = 0; axis < 2; ++axis) EXPECT_TRUE(tracking.covariance(axis).allFinite());
}

TEST(LinearDynamicsRls, RefusesBadInput) {
  LinearDynamicsRlsOptions bad;
  bad.forgetting_per_s = 1.5;
  EXPECT_THROW(LinearDynamicsRls(Eigen::MatrixXd::Zero(2, kColumns), bad), std::invalid_argument);
  EXPECT_THROW(LinearDynamicsRls(Eigen::MatrixXd::Zero(3, kColumns), LinearDynamicsRlsOptions()),
               std::invalid_argument);
  LinearDynamicsRls rls(Eigen::MatrixXd::Zero(2, kColumns), LinearDynamicsRlsOptions());
  LinearDynamicsEvidence other = stream(response(0.2), 1.0, 0.0, 0.1, 6);
  other.along_x.conservativeResize(Eigen::NoChange, kColumns - 1);
  EXPECT_THROW(rls.add(other), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
