// The package's one nonlinear least-squares solver, and its one robust ridge regression.
//
// Every fit in core states its problem the same way: a residual functor over named parameters
// (bounds, a logarithmic coordinate, a forward-difference step, held or free), residuals grouped
// in blocks on which one robust loss acts, and gets back one report: the values, the cost at the
// start and the end, the iterations and evaluations spent, and why it stopped. The minimiser
// underneath is the package's own damped Gauss-Newton (the default), Ceres' trust region or Eigen's
// MINPACK port; docs/solver.md compares them and says how to use them.
//
// Conventions (fixed once, as Ceres writes them):
//  - cost = 1/2 sum_b rho(|r_b|^2) over the loss's blocks r_b, plus 1/2 |r|^2 over the residuals
//    outside the loss (priors, ties);
//  - Huber:  rho(s) = s for s <= a^2, 2 a sqrt(s) - a^2 beyond (a = the loss's scale, in the
//    residual's units: the block norm where it stops being a square);
//    Cauchy: rho(s) = a^2 log(1 + s / a^2);
//  - a block's robust weight (what an iteratively re-weighted solve multiplies it by) is rho'(s):
//    Huber 1 inside a and a / |r| beyond, Cauchy 1 / (1 + s / a^2).
//
// A fit that builds its own normal equations states its problem by its linearisation instead
// (LinearisedLeastSquaresProblem) and runs the same Levenberg-Marquardt.
//
// Pure C++ (Eigen, Ceres): no ROS, no OpenCV.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace deep_ois {

// A robust loss on a block's squared norm s (see the conventions above).
struct RobustLoss {
  enum class Kind { kNone, kHuber, kCauchy };
  Kind kind = Kind::kNone;
  double scale = 1.0;  // a: block norm where the loss leaves the square (residual units, > 0)

  static RobustLoss none() { return {}; }
  static RobustLoss huber(double scale) { return {Kind::kHuber, scale}; }
  static RobustLoss cauchy(double scale) { return {Kind::kCauchy, scale}; }

  double rho(double squared_norm) const;
  // rho'(s): the weight an iteratively re-weighted least squares gives the block.
  double weight(double squared_norm) const;
  // An empty string, or what is wrong (a scale that is not positive and finite).
  std::string validate() const;
};

// One parameter of a problem, as the solver moves it.
struct SolverParameter {
  std::string name;
  double lower = -std::numeric_limits<double>::infinity();  // in the parameter's own unit
  double upper = std::numeric_limits<double>::infinity();
  // Solved as log(value): for a positive quantity whose scale spans decades (corners, bandwidths).
  // Needs lower > 0.
  bool logarithmic = false;
  // Forward-difference step in the solved coordinate (the logarithm for a logarithmic one), used
  // when the problem gives no Jacobian. > 0.
  double difference_step = 1e-6;
  bool held = false;  // kept at its start value
};

// A problem: parameters, residuals at given parameter values and, optionally, their Jacobian.
struct NonlinearLeastSquaresProblem {
  std::vector<SolverParameter> parameters;
  // The residuals at `values` (one per parameter, inside their bounds). Returns false when the
  // model cannot be evaluated there (a step to such values is refused). The residual count must
  // not change from one call to the next: return false when it would.
  std::function<bool(const Eigen::VectorXd& values, Eigen::VectorXd* residuals)> residuals;
  // Optional: residuals and their Jacobian with respect to the values (residuals x parameters;
  // held parameters' columns are ignored). Without it, forward differences of `residuals`.
  std::function<bool(const Eigen::VectorXd& values, Eigen::VectorXd* residuals,
                     Eigen::MatrixXd* jacobian)>
      residuals_and_jacobian;
  // The loss acts on blocks of this many consecutive residuals (2 for a 2-D image residual).
  int block_size = 1;
  // Residuals from this index on are outside the loss (priors, ties): plain squares. Negative:
  // every residual is under the loss. Must be a multiple of block_size.
  long robust_residual_count = -1;
};

enum class SolverEngine {
  // The package's damped Gauss-Newton (minimiseLevenbergMarquardt below): the robust loss as
  // iteratively re-weighted least squares, Marquardt's diagonal damping on a fixed schedule. The
  // default: on the stabiliser fit it converges as far as Ceres at a fraction of its CPU.
  kLevenbergMarquardt,
  kCeres,                     // ceres::Solve, trust-region Levenberg-Marquardt
  kEigenLevenbergMarquardt,   // Eigen's unsupported/NonLinearOptimization (MINPACK lmder)
};
const char* solverEngineName(SolverEngine engine);  // "levenberg_marquardt", "ceres", "eigen"

// The damping of kLevenbergMarquardt: a step solves (H + lambda diag(H_jj + 1e-9)) dx = -g.
struct DampingSchedule {
  double initial = 1e-2;   // lambda at the first iteration (relative to the diagonal)
  double decrease = 3.0;   // lambda /= decrease after an accepted step
  double increase = 10.0;  // lambda *= increase after a refused one
  double minimum = 1e-7;   // lambda never falls below this
  int attempts = 8;        // refused steps in one iteration before the solve stops (no progress)
  std::string validate() const;
};

struct NonlinearLeastSquaresOptions {
  RobustLoss loss;
  SolverEngine engine = SolverEngine::kLevenbergMarquardt;
  int max_iterations = 50;  // accepted steps (Jacobian evaluations) for every engine, >= 1
  DampingSchedule damping;  // kLevenbergMarquardt only
  // Converged when an iteration lowers the cost by less than this fraction of it.
  double function_tolerance = 1e-6;
  // Converged when a step changes the solved coordinates by less than this, relative.
  double parameter_tolerance = 1e-8;
  // Converged when the gradient's largest entry falls below this (Ceres only).
  double gradient_tolerance = 1e-10;
  std::string validate() const;
};

enum class SolverTermination {
  kConverged,       // a tolerance was met
  kIterationLimit,  // max_iterations reached first
  kNoProgress,      // no step lowered the cost any more (a minimum to the solver's resolution)
  kFailed,          // the problem could not be evaluated at the start, or the engine failed
};
const char* solverTerminationName(SolverTermination termination);

struct NonlinearLeastSquaresReport {
  Eigen::VectorXd values;  // the solution, one per parameter, inside the bounds
  double initial_cost = 0.0, final_cost = 0.0;  // the conventions' cost
  int iterations = 0;                           // accepted steps (Jacobian evaluations)
  int residual_evaluations = 0;                 // calls of the residual functor, differences included
  SolverTermination termination = SolverTermination::kFailed;
  std::string message;  // the engine's own words on why it stopped
  std::vector<std::string> on_bound;  // names of free parameters that ended on a bound
  // After each accepted step: the RMS of the blocks' norms, without the loss (residual units).
  std::vector<double> rms_history;
  double cpu_s = 0.0;  // process CPU time the solve took

  bool usable() const { return termination != SolverTermination::kFailed; }
  // One line: engine's reason, iterations, evaluations, cost from and to, bounds hit.
  std::string summary() const;
};

// Minimises the problem's cost from `start` (one value per parameter; values outside a bound are
// moved onto it). Throws std::invalid_argument naming what is wrong with the problem, the start
// or the options; a model that cannot be evaluated at the start gives a kFailed report.
NonlinearLeastSquaresReport solveNonlinearLeastSquares(const NonlinearLeastSquaresProblem& problem,
                                                       const Eigen::VectorXd& start,
                                                       const NonlinearLeastSquaresOptions& options);

// A problem stated by its linearisation, for a fit that builds its own normal equations (e.g. the
// camera-IMU calibration, which eliminates a lens shift per frame by a Schur complement before
// the step and re-scales its loss between iterations). The solver keeps the current point's
// linearisation; the problem keeps the point.
class LinearisedLeastSquaresProblem {
 public:
  virtual ~LinearisedLeastSquaresProblem() = default;
  // At the current point: the cost and the normal equations of its linearisation, the step
  // solving (normal + damping) step = -gradient. False: the point cannot be evaluated.
  virtual bool linearise(double* cost, Eigen::MatrixXd* normal, Eigen::VectorXd* gradient) = 0;
  // The cost at the current point moved by `step`, in linearise's terms (the point stays). False:
  // the moved point cannot be evaluated (the step is refused).
  virtual bool trialCost(const Eigen::VectorXd& step, double* cost) = 0;
  // Moves the current point by `step`, the last one trialCost saw (it lowered the cost). Returns
  // true when the problem's own test says the fit has converged.
  virtual bool accept(const Eigen::VectorXd& step) = 0;
};

// The package's Levenberg-Marquardt (engine kLevenbergMarquardt of solveNonlinearLeastSquares):
// per iteration one linearisation, then steps with the damping of `options.damping` until one
// lowers the cost; stops at `max_iterations` accepted steps, when a step lowers the cost by less
// than `function_tolerance` of it or the problem's own test says so (kConverged), or when no step
// within `damping.attempts` lowers it (kNoProgress). The report's `values` stay empty.
NonlinearLeastSquaresReport minimiseLevenbergMarquardt(LinearisedLeastSquaresProblem& problem,
                                                       const NonlinearLeastSquaresOptions& options);

// Robust weighted ridge regression with several outputs, the package's one ridge convention:
// the coefficients B (features x outputs) minimise
//   sum_i w_i |t_i - B^T f_i|^2 + sum_k (ridge A_kk + floor) |B_k - P_k|^2,
// with A = sum_i w_i f_i f_i^T, P a prior (zero unless given), floor = 1e-12 max_k A_kk (so a
// silent feature is held at its prior instead of making the system singular). The ridge is
// relative to each feature's own energy A_kk: features that differ by orders of magnitude are
// pulled alike, and the ridge is unitless. The weights w_i are the observation's data weight
// times the loss's weight rho'(|e_i|^2) of a reference residual e_i the caller gives (the residual
// of the model being refined: one re-weighting pass). The closed form:
//   (A + D) B = sum_i w_i f_i t_i^T + D P,   D = diag(ridge A_kk + floor).
class RobustRidgeRegression {
 public:
  RobustRidgeRegression(long feature_count, long output_count, RobustLoss loss);
  // Adds one observation: features f (feature_count), target t (output_count), data weight >= 0
  // and the norm of its reference residual (same units as the target).
  void add(const Eigen::VectorXd& features, const Eigen::VectorXd& target, double data_weight,
           double reference_residual_norm);
  std::size_t count() const { return count_; }
  // The coefficients (feature_count x output_count), or false when there is no observation or the
  // solve is not finite. `prior` (feature_count x output_count) or null for zero.
  bool solve(double ridge, Eigen::MatrixXd* coefficients, const Eigen::MatrixXd* prior = nullptr) const;

 private:
  RobustLoss loss_;
  Eigen::MatrixXd normal_, right_;  // A and sum w f t^T
  std::size_t count_ = 0;
};

}  // namespace deep_ois
