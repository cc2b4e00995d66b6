// The one solver of core (core/common/nonlinear_least_squares.h): a known nonlinear problem with
// outliers recovered under the robust loss by both engines, bounds and logarithmic parameters
// respected, the analytic and the difference Jacobian agreeing, and the ridge convention's closed
// form.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "deep_ois/core/common/nonlinear_least_squares.h"

namespace deep_ois {
namespace {

// y = a exp(-b t) + c, sampled on [0, 4] s with noise 0.01 and every 7th sample an outlier (+-2).
struct DecayData {
  Eigen::VectorXd t, y;
};
constexpr double kA = 2.0, kB = 1.3, kC = 0.4;

DecayData decayData(bool outliers) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  DecayData d;
  const int n = 120;
  d.t.resize(n);
  d.y.resize(n);
  for (int i = 0; i < n; ++i) {
    d.t(i) = 4.0 * i / (n - 1);
    d.y(i) = kA * std::exp(-kB * d.t(i)) + kC + noise(rng);
    if (outliers && i % 7 == 3) d.y(i) += (i % 2 ? 2.0 : -1.5);
  }
  return d;
}

NonlinearLeastSquaresProblem decayProblem(const DecayData& d, bool analytic) {
  NonlinearLeastSquaresProblem problem;
  problem.parameters = {{"a"}, {"b", 1e-3, 100.0, true, 1e-6}, {"c"}};
  problem.residuals = [&d](const Eigen::VectorXd& v, Eigen::VectorXd* r) {
    *r = (v(0) * (-v(1) * d.t.array()).exp() + v(2)).matrix() - d.y;
    return true;
  };
  if (analytic) {
    problem.residuals_and_jacobian = [&d](const Eigen::VectorXd& v, Eigen::VectorXd* r, Eigen::MatrixXd* J) {
      const Eigen::ArrayXd e = (-v(1) * d.t.array()).exp();
      *r = (v(0) * e + v(2)).matrix() - d.y;
      J->resize(d.t.size(), 3);
      J->col(0) = e.matrix();
      J->col(1) = (-v(0) * d.t.array() * e).matrix();
      J->col(2).setOnes();
      return true;
    };
  }
  return problem;
}

const Eigen::Vector3d kStart(1.0, 0.5, 0.0);

constexpr SolverEngine kEngines[] = {SolverEngine::kLevenbergMarquardt, SolverEngine::kCeres,
                                     SolverEngine::kEigenLevenbergMarquardt};

TEST(RobustLoss, FollowsCeresConventions) {
  const RobustLoss huber = RobustLoss::huber(2.0);
  EXPECT_DOUBLE_EQ(huber.rho(1.0), 1.0);               // inside: the square
  EXPECT_DOUBLE_EQ(huber.rho(9.0), 2.0 * 2.0 * 3.0 - 4.0);  // beyond: 2 a |r| - a^2
  EXPECT_DOUBLE_EQ(huber.weight(9.0), 2.0 / 3.0);      // a / |r|
  const RobustLoss cauchy = RobustLoss::cauchy(2.0);
  EXPECT_DOUBLE_EQ(cauchy.rho(4.0), 4.0 * std::log(2.0));
  EXPECT_DOUBLE_EQ(cauchy.weight(4.0), 0.5);
  EXPECT_FALSE(RobustLoss::huber(0.0).validate().empty());
}

TEST(NonlinearLeastSquares, RecoversADecayThroughOutliersWithEveryEngine) {
  const DecayData d = decayData(true);
  for (SolverEngine engine : kEngines) {
    NonlinearLeastSquaresOptions options;
    options.engine = engine;
    options.loss = RobustLoss::huber(0.05);
    const NonlinearLeastSquaresReport robust = solveNonlinearLeastSquares(decayProblem(d, false), kStart, options);
    SCOPED_TRACE(robust.summary());
    EXPECT_EQ(robust.termination, SolverTermination::kConverged);
    EXPECT_NEAR(robust.values(0), kA, 0.03);
    EXPECT_NEAR(robust.values(1), kB, 0.03);
    EXPECT_NEAR(robust.values(2), kC, 0.01);
    EXPECT_LT(robust.final_cost, robust.initial_cost);
    EXPECT_FALSE(robust.rms_history.empty());
    // The same data without the loss: the outliers pull the fit off (what the loss is for).
    options.loss = RobustLoss::none();
    const NonlinearLeastSquaresReport plain = solveNonlinearLeastSquares(decayProblem(d, false), kStart, options);
    EXPECT_GT(std::abs(plain.values(2) - kC), 0.05) << plain.summary();
  }
}

TEST(NonlinearLeastSquares, AnalyticAndDifferenceJacobiansAgreeUnderCauchy) {
  const DecayData d = decayData(true);
  NonlinearLeastSquaresOptions options;
  options.loss = RobustLoss::cauchy(0.05);
  const auto numeric = solveNonlinearLeastSquares(decayProblem(d, false), kStart, options);
  const auto analytic = solveNonlinearLeastSquares(decayProblem(d, true), kStart, options);
  EXPECT_NEAR(numeric.values(1), kB, 0.03);
  EXPECT_LT((numeric.values - analytic.values).norm(), 1e-4);
  // The analytic Jacobian costs no difference evaluations.
  EXPECT_LT(analytic.residual_evaluations, numeric.residual_evaluations);
}

TEST(NonlinearLeastSquares, KeepsBoundsAndHeldParameters) {
  const DecayData d = decayData(false);
  for (SolverEngine engine : kEngines) {
    NonlinearLeastSquaresProblem problem = decayProblem(d, false);
    problem.parameters[1].upper = 1.0;  // below the true 1.3
    problem.parameters[2].held = true;  // c stays at its start
    NonlinearLeastSquaresOptions options;
    options.engine = engine;
    const auto report = solveNonlinearLeastSquares(problem, Eigen::Vector3d(1.0, 0.5, kC), options);
    SCOPED_TRACE(report.summary());
    EXPECT_LE(report.values(1), 1.0);
    EXPECT_NEAR(report.values(1), 1.0, 1e-6);
    EXPECT_EQ(report.values(2), kC);
    ASSERT_EQ(report.on_bound.size(), 1u);
    EXPECT_EQ(report.on_bound[0], "b");
  }
  // A start outside a bound is moved onto it.
  NonlinearLeastSquaresProblem problem = decayProblem(d, false);
  problem.parameters[1].upper = 1.0;
  NonlinearLeastSquaresOptions once;
  once.max_iterations = 1;
  const auto capped = solveNonlinearLeastSquares(problem, Eigen::Vector3d(1.0, 5.0, 0.0), once);
  EXPECT_LE(capped.values(1), 1.0);
  EXPECT_EQ(capped.termination, SolverTermination::kIterationLimit);
}

TEST(NonlinearLeastSquares, SaysWhyItFailedOrRefused) {
  const DecayData d = decayData(false);
  NonlinearLeastSquaresProblem problem = decayProblem(d, false);
  problem.residuals = [](const Eigen::VectorXd&, Eigen::VectorXd*) { return false; };
  const auto failed = solveNonlinearLeastSquares(problem, kStart, {});
  EXPECT_EQ(failed.termination, SolverTermination::kFailed);
  EXPECT_FALSE(failed.usable());
  // Bad input names the problem.
  NonlinearLeastSquaresProblem bad = decayProblem(d, false);
  bad.parameters[1].lower = 0.0;  // logarithmic needs > 0
  try {
    solveNonlinearLeastSquares(bad, kStart, {});
    FAIL() << "a logarithmic parameter with a zero lower bound was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'b'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(solveNonlinearLeastSquares(decayProblem(d, false), Eigen::Vector2d(1.0, 1.0), {}),
               std::invalid_argument);
}

// Rosenbrock's valley, r = (10 (y - x^2), 1 - x), stated by its normal equations; its own test
// stops the fit once a step is below 1e-9.
class Rosenbrock : public LinearisedLeastSquaresProblem {
 public:
  Eigen::Vector2d point{-1.2, 1.0};
  int own_test_steps = 0;
  bool linearise(double* cost, Eigen::MatrixXd* normal, Eigen::VectorXd* gradient) override {
    const Eigen::Vector2d r = residuals(point);
    Eigen::Matrix2d J;
    J << -20.0 * point.x(), 10.0, -1.0, 0.0;
    *cost = 0.5 * r.squaredNorm();
    *normal = J.transpose() * J;
    *gradient = J.transpose() * r;
    return true;
  }
  bool trialCost(const Eigen::VectorXd& step, double* cost) override {
    *cost = 0.5 * residuals(point + step).squaredNorm();
    return true;
  }
  bool accept(const Eigen::VectorXd& step) override {
    point += step;
    if (step.norm() < 1e-9) ++own_test_steps;
    return step.norm() < 1e-9;
  }

 private:
  static Eigen::Vector2d residuals(const Eigen::Vector2d& p) {
    return Eigen::Vector2d(10.0 * (p.y() - p.x() * p.x()), 1.0 - p.x());
  }
};

TEST(LevenbergMarquardt, FollowsALinearisedProblemToItsMinimum) {
  Rosenbrock valley;
  NonlinearLeastSquaresOptions options;
  options.function_tolerance = 0.0;  // the problem's own test decides
  options.max_iterations = 200;
  const NonlinearLeastSquaresReport report = minimiseLevenbergMarquardt(valley, options);
  SCOPED_TRACE(report.summary());
  EXPECT_NEAR(valley.point.x(), 1.0, 1e-6);
  EXPECT_NEAR(valley.point.y(), 1.0, 1e-6);
  EXPECT_EQ(report.termination, SolverTermination::kConverged);
  EXPECT_EQ(valley.own_test_steps, 1);
  EXPECT_NEAR(report.initial_cost, 12.1, 1e-12);
  EXPECT_LT(report.final_cost, 1e-12);
  // Capped, it says so.
  Rosenbrock capped;
  options.max_iterations = 3;
  EXPECT_EQ(minimiseLevenbergMarquardt(capped, options).termination, SolverTermination::kIterationLimit);
  // A schedule that cannot damp is refused by name.
  options.damping.increase = 1.0;
  try {
    minimiseLevenbergMarquardt(capped, options);
    FAIL() << "a damping schedule that never increases was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("damping.increase"), std::string::npos) << e.what();
  }
}

TEST(RobustRidgeRegression, MatchesTheClosedFormAndPullsTowardsThePrior) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  const long m = 3, outputs = 2, n = 200;
  Eigen::MatrixXd F(n, m), T(n, outputs);
  Eigen::VectorXd w(n);
  Eigen::MatrixXd truth(m, outputs);
  truth << 1.0, -2.0, 0.5e-2, 3.0e-2, -1.0e2, 0.25e2;  // each feature moves the target alike
  for (long i = 0; i < n; ++i) {
    // Features on scales a hundred apart: the ridge is relative to each one's energy.
    F.row(i) << normal(rng), 1e2 * normal(rng), 1e-2 * normal(rng);
    T.row(i) = F.row(i) * truth;  // exact: the ridge alone moves the coefficients
    w(i) = 0.5 + (i % 3);
  }
  const double ridge = 0.1;
  RobustRidgeRegression regression(m, outputs, RobustLoss::huber(1.0));
  for (long i = 0; i < n; ++i) regression.add(F.row(i).transpose(), T.row(i).transpose(), w(i), 0.0);
  Eigen::MatrixXd fitted;
  ASSERT_TRUE(regression.solve(ridge, &fitted));
  // The closed form (reference residuals 0: every robust weight is 1).
  const Eigen::MatrixXd A = F.transpose() * w.asDiagonal() * F;
  const Eigen::VectorXd penalty = (ridge * A.diagonal()).array() + 1e-12 * A.diagonal().maxCoeff();
  const Eigen::MatrixXd expected =
      (A + Eigen::MatrixXd(penalty.asDiagonal())).ldlt().solve(F.transpose() * w.asDiagonal() * T);
  EXPECT_LT((fitted - expected).norm(), 1e-9 * expected.norm());
  // Every feature is shrunk by about the same factor 1 / (1 + ridge) (random features are nearly
  // orthogonal), whatever its scale.
  for (long k = 0; k < m; ++k) EXPECT_NEAR(fitted(k, 0) / truth(k, 0), 1.0 / (1.0 + ridge), 0.05);
  // A huge ridge holds the coefficients at the prior.
  Eigen::MatrixXd prior = Eigen::MatrixXd::Constant(m, outputs, 0.7), held;
  ASSERT_TRUE(regression.solve(1e12, &held, &prior));
  EXPECT_LT((held - prior).norm(), 1e-6);
  // An observation whose reference residual is far beyond the Huber scale weighs a / |e|.
  RobustRidgeRegression one(1, 1, RobustLoss::huber(1.0));
  one.add(Eigen::VectorXd::Constant(1, 1.0), Eigen::VectorXd::Constant(1, 0.0), 1.0, 0.0);
  one.add(Eigen::VectorXd::Constant(1, 1.0), Eigen::VectorXd::Constant(1, 10.0), 1.0, 10.0);
  Eigen::MatrixXd mean;
  ASSERT_TRUE(one.solve(0.0, &mean));
  EXPECT_NEAR(mean(0, 0), (0.0 + 0.1 * 10.0) / 1.1, 1e-9);
}

}  // namespace
}  // namespace deep_ois
