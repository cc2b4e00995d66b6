#include "deep_ois/core/common/nonlinear_least_squares.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <ctime>
#include <sstream>
#include <stdexcept>
#include <unsupported/Eigen/NonLinearOptimization>

namespace deep_ois {

double RobustLoss::rho(double s) const {
  const double a2 = scale * scale;
  switch (kind) {
    case Kind::kNone:
      return s;
    case Kind::kHuber:
      return s <= a2 ? s : 2.0 * scale * std::sqrt(s) - a2;
    case Kind::kCauchy:
      return a2 * std::log1p(s / a2);
  }
  return s;
}

double RobustLoss::weight(double s) const {
  const double a2 = scale * scale;
  switch (kind) {
    case Kind::kNone:
      return 1.0;
    case Kind::kHuber:
      return s <= a2 ? 1.0 : scale / std::sqrt(s);
    case Kind::kCauchy:
      return 1.0 / (1.0 + s / a2);
  }
  return 1.0;
}

std::string RobustLoss::validate() const {
  if (kind != Kind::kNone && !(scale > 0.0 && std::isfinite(scale))) {
    std::ostringstream why;
    why << "robust loss: the scale must be positive and finite (got " << scale << ")";
    return why.str();
  }
  return "";
}

std::string NonlinearLeastSquaresOptions::validate() const {
  const std::string loss_problem = loss.validate();
  if (!loss_problem.empty()) return loss_problem;
  std::ostringstream why;
  if (max_iterations < 1) why << "max_iterations must be >= 1 (got " << max_iterations << ")";
  else if (!(function_tolerance >= 0.0)) why << "function_tolerance must be >= 0";
  else if (!(parameter_tolerance >= 0.0)) why << "parameter_tolerance must be >= 0";
  else if (!(gradient_tolerance >= 0.0)) why << "gradient_tolerance must be >= 0";
  else return damping.validate();
  return why.str();
}

const char* solverEngineName(SolverEngine engine) {
  switch (engine) {
    case SolverEngine::kLevenbergMarquardt:
      return "levenberg_marquardt";
    case SolverEngine::kCeres:
      return "ceres";
    case SolverEngine::kEigenLevenbergMarquardt:
      return "eigen";
  }
  return "unknown";
}

std::string DampingSchedule::validate() const {
  std::ostringstream why;
  if (!(initial > 0.0 && std::isfinite(initial))) why << "damping.initial must be positive (got " << initial << ")";
  else if (!(decrease >= 1.0 && std::isfinite(decrease))) why << "damping.decrease must be >= 1 (got " << decrease << ")";
  else if (!(increase > 1.0 && std::isfinite(increase))) why << "damping.increase must be > 1 (got " << increase << ")";
  else if (!(minimum >= 0.0 && minimum <= initial)) why << "damping.minimum must be in [0, initial] (got " << minimum << ")";
  else if (attempts < 1) why << "damping.attempts must be >= 1 (got " << attempts << ")";
  return why.str();
}

const char* solverTerminationName(SolverTermination termination) {
  switch (termination) {
    case SolverTermination::kConverged:
      return "converged";
    case SolverTermination::kIterationLimit:
      return "iteration limit";
    case SolverTermination::kNoProgress:
      return "no further progress";
    case SolverTermination::kFailed:
      return "failed";
  }
  return "failed";
}

std::string NonlinearLeastSquaresReport::summary() const {
  std::ostringstream out;
  out << solverTerminationName(termination) << " after " << iterations << " iterations, "
      << residual_evaluations << " residual evaluations, cost " << initial_cost << " -> "
      << final_cost;
  if (!on_bound.empty()) {
    out << ", on a bound:";
    for (const std::string& name : on_bound) out << " " << name;
  }
  if (!message.empty()) out << " (" << message << ")";
  return out.str();
}

namespace {

double processCpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

// The free parameters' solved coordinates z (the logarithm for a logarithmic one) and the map
// back to every parameter's value, held in the bounds.
class Coordinates {
 public:
  Coordinates(const std::vector<SolverParameter>& parameters, const Eigen::VectorXd& start)
      : parameters_(parameters), start_(start) {
    for (std::size_t j = 0; j < parameters.size(); ++j) {
      const SolverParameter& p = parameters[j];
      start_(static_cast<long>(j)) = std::clamp(start(static_cast<long>(j)), p.lower, p.upper);
      if (p.held) continue;
      free_.push_back(static_cast<long>(j));
      lower_.push_back(p.logarithmic ? std::log(p.lower) : p.lower);
      upper_.push_back(p.logarithmic ? std::log(p.upper) : p.upper);
    }
  }
  long size() const { return static_cast<long>(free_.size()); }
  long index(long k) const { return free_[static_cast<std::size_t>(k)]; }
  double lower(long k) const { return lower_[static_cast<std::size_t>(k)]; }
  double upper(long k) const { return upper_[static_cast<std::size_t>(k)]; }
  const SolverParameter& parameter(long k) const { return parameters_[static_cast<std::size_t>(index(k))]; }

  Eigen::VectorXd startCoordinates() const {
    Eigen::VectorXd z(size());
    for (long k = 0; k < size(); ++k) {
      const double value = start_(index(k));
      z(k) = parameter(k).logarithmic ? std::log(value) : value;
    }
    return z;
  }
  double clamped(long k, double z) const { return std::clamp(z, lower(k), upper(k)); }
  Eigen::VectorXd values(const Eigen::VectorXd& z) const {
    Eigen::VectorXd v = start_;
    for (long k = 0; k < size(); ++k) {
      const double c = clamped(k, z(k));
      v(index(k)) = parameter(k).logarithmic ? std::exp(c) : c;
    }
    return v;
  }
  // d value / d z of free parameter k at z (zero where the bound holds it).
  double derivative(long k, double z) const {
    if (z < lower(k) || z > upper(k)) return 0.0;
    return parameter(k).logarithmic ? std::exp(z) : 1.0;
  }

 private:
  const std::vector<SolverParameter>& parameters_;
  Eigen::VectorXd start_;
  std::vector<long> free_;
  std::vector<double> lower_, upper_;
};

// The problem in the free coordinates with the loss folded into its residuals: each robust block
// r becomes phi(s) r with phi = sqrt(rho(s) / s), so 1/2 |corrected|^2 is the cost and both
// engines see a plain least-squares problem (the same function for both).
class CorrectedProblem {
 public:
  CorrectedProblem(const NonlinearLeastSquaresProblem& problem, const Coordinates& coordinates,
                   const RobustLoss& loss)
      : problem_(problem), coordinates_(coordinates), loss_(loss) {}

  long residualCount() const { return residual_count_; }
  int evaluations() const { return evaluations_; }
  double lastRms() const { return last_rms_; }

  // Corrected residuals at z and, when `jacobian` is given, their Jacobian over z.
  bool evaluate(const Eigen::VectorXd& z, Eigen::VectorXd* corrected, Eigen::MatrixXd* jacobian) {
    const Eigen::VectorXd values = coordinates_.values(z);
    Eigen::VectorXd raw;
    Eigen::MatrixXd raw_jacobian;
    const bool analytic = jacobian != nullptr && static_cast<bool>(problem_.residuals_and_jacobian);
    ++evaluations_;
    const bool ok = analytic ? problem_.residuals_and_jacobian(values, &raw, &raw_jacobian)
                             : problem_.residuals(values, &raw);
    if (!ok || !countMatches(raw) || !raw.allFinite()) return false;
    Eigen::VectorXd phi, phi_slope;
    correct(raw, corrected, &phi, &phi_slope);
    last_rms_ = blockRms(raw);  // both engines' last evaluation before a step is accepted is there
    if (jacobian == nullptr) return true;
    const long n = coordinates_.size();
    jacobian->resize(residual_count_, n);
    if (analytic) {
      checkJacobianSize(raw_jacobian);
      for (long k = 0; k < n; ++k)
        jacobian->col(k) = raw_jacobian.col(coordinates_.index(k)) * coordinates_.derivative(k, z(k));
      // Through the correction: d(phi r) = (phi I + 2 phi'(s) r r^T) dr per robust block.
      const int b = problem_.block_size;
      for (long block = 0; block < phi.size(); ++block) {
        const Eigen::VectorXd r = raw.segment(block * b, b);
        Eigen::MatrixXd rows = jacobian->middleRows(block * b, b);
        jacobian->middleRows(block * b, b) =
            phi(block) * rows + (2.0 * phi_slope(block)) * r * (r.transpose() * rows);
      }
      return jacobian->allFinite();
    }
    differences(z, *corrected, true, jacobian);
    return true;
  }

  // The residuals at z without the loss and, when `jacobian` is given, their Jacobian over z.
  // `raw_known`: *raw already holds the residuals at z (only the Jacobian is evaluated).
  bool evaluateRaw(const Eigen::VectorXd& z, Eigen::VectorXd* raw, Eigen::MatrixXd* jacobian,
                   bool raw_known = false) {
    const Eigen::VectorXd values = coordinates_.values(z);
    Eigen::MatrixXd raw_jacobian;
    const bool analytic = jacobian != nullptr && static_cast<bool>(problem_.residuals_and_jacobian);
    if (raw_known && !analytic) {
      differences(z, *raw, false, jacobian);
      return true;
    }
    ++evaluations_;
    const bool ok = analytic ? problem_.residuals_and_jacobian(values, raw, &raw_jacobian)
                             : problem_.residuals(values, raw);
    if (!ok || !countMatches(*raw) || !raw->allFinite()) return false;
    last_rms_ = blockRms(*raw);
    if (jacobian == nullptr) return true;
    if (!analytic) {
      differences(z, *raw, false, jacobian);
      return true;
    }
    checkJacobianSize(raw_jacobian);
    jacobian->resize(residual_count_, coordinates_.size());
    for (long k = 0; k < coordinates_.size(); ++k)
      jacobian->col(k) = raw_jacobian.col(coordinates_.index(k)) * coordinates_.derivative(k, z(k));
    return jacobian->allFinite();
  }

  // The cost of raw residuals (the conventions' 1/2 sum rho plus 1/2 the priors' squares).
  double rawCost(const Eigen::VectorXd& raw) const {
    Eigen::VectorXd corrected;
    correct(raw, &corrected, nullptr, nullptr);
    return cost(corrected);
  }
  // Each residual's robust weight rho'(|block|^2) (1 outside the loss).
  Eigen::VectorXd weights(const Eigen::VectorXd& raw) const {
    Eigen::VectorXd w = Eigen::VectorXd::Ones(raw.size());
    if (loss_.kind == RobustLoss::Kind::kNone) return w;
    const int b = problem_.block_size;
    for (long block = 0; block < robust_blocks_; ++block)
      w.segment(block * b, b).setConstant(loss_.weight(raw.segment(block * b, b).squaredNorm()));
    return w;
  }

  // The corrected residuals' 1/2 |.|^2 is the cost.
  static double cost(const Eigen::VectorXd& corrected) { return 0.5 * corrected.squaredNorm(); }

  // Over the loss's blocks (the data), not the priors after them.
  double blockRms(const Eigen::VectorXd& raw) const {
    const long blocks = robust_blocks_ > 0 ? robust_blocks_ : raw.size() / problem_.block_size;
    const double sum = raw.head(blocks * problem_.block_size).squaredNorm();
    return blocks > 0 ? std::sqrt(sum / static_cast<double>(blocks)) : 0.0;
  }

 private:
  void checkJacobianSize(const Eigen::MatrixXd& raw_jacobian) const {
    if (raw_jacobian.rows() != residual_count_ ||
        raw_jacobian.cols() != static_cast<long>(problem_.parameters.size()))
      throw std::invalid_argument("nonlinear least squares: the Jacobian is " +
                                  std::to_string(raw_jacobian.rows()) + " x " +
                                  std::to_string(raw_jacobian.cols()) + ", expected " +
                                  std::to_string(residual_count_) + " x " +
                                  std::to_string(problem_.parameters.size()));
  }

  // Forward differences of the residuals (corrected by the loss or raw) around `reference`, the
  // residuals at z, stepping back from a point the model cannot be evaluated at and, for the
  // library engines (`corrected`), from an upper bound; a parameter that cannot move either way
  // gets a zero column (held for this iteration). The package's engine differences the raw
  // residuals forward only, the step held in the bounds, as its hand-written loops did: a
  // parameter on its upper bound then has a zero column and stays there (stepping it back moved
  // the strokes of the online learner's first fit off their bounds and into a worse minimum).
  void differences(const Eigen::VectorXd& z, const Eigen::VectorXd& reference, bool corrected,
                   Eigen::MatrixXd* jacobian) {
    jacobian->resize(residual_count_, coordinates_.size());
    for (long k = 0; k < coordinates_.size(); ++k) {
      const double step = coordinates_.parameter(k).difference_step;
      const double first = corrected && z(k) + step > coordinates_.upper(k) ? -step : step;
      jacobian->col(k).setZero();
      for (double h : {first, -first}) {
        Eigen::VectorXd moved = z;
        moved(k) += h;
        Eigen::VectorXd moved_raw, moved_corrected;
        ++evaluations_;
        if (!problem_.residuals(coordinates_.values(moved), &moved_raw) ||
            moved_raw.size() != residual_count_ || !moved_raw.allFinite())
          continue;
        if (corrected) correct(moved_raw, &moved_corrected, nullptr, nullptr);
        jacobian->col(k) = ((corrected ? moved_corrected : moved_raw) - reference) / h;
        break;
      }
    }
  }

  bool countMatches(const Eigen::VectorXd& raw) {
    if (residual_count_ < 0) {
      residual_count_ = raw.size();
      const long robust = problem_.robust_residual_count < 0 ? residual_count_ : problem_.robust_residual_count;
      if (robust > residual_count_ || robust % problem_.block_size != 0)
        throw std::invalid_argument(
            "nonlinear least squares: robust_residual_count " + std::to_string(robust) +
            " must be at most the residual count " + std::to_string(residual_count_) +
            " and a multiple of block_size " + std::to_string(problem_.block_size));
      robust_blocks_ = robust / problem_.block_size;
    }
    return raw.size() == residual_count_;
  }

  void correct(const Eigen::VectorXd& raw, Eigen::VectorXd* corrected, Eigen::VectorXd* phi,
               Eigen::VectorXd* phi_slope) const {
    *corrected = raw;
    if (phi) phi->setOnes(robust_blocks_);
    if (phi_slope) phi_slope->setZero(robust_blocks_);
    if (loss_.kind == RobustLoss::Kind::kNone) return;
    const int b = problem_.block_size;
    const double a2 = loss_.scale * loss_.scale;
    for (long block = 0; block < robust_blocks_; ++block) {
      const double s = raw.segment(block * b, b).squaredNorm();
      double f = 1.0, slope = 0.0;
      if (loss_.kind == RobustLoss::Kind::kCauchy && s < 1e-8 * a2) {
        slope = -0.25 / a2;  // the series of sqrt(log1p(s/a2) a2 / s) at 0
      } else if (s > 0.0 && loss_.rho(s) < s) {
        const double rho = loss_.rho(s);
        f = std::sqrt(rho / s);
        slope = (loss_.weight(s) * s - rho) / (2.0 * f * s * s);
      }
      corrected->segment(block * b, b) *= f;
      if (phi) (*phi)(block) = f;
      if (phi_slope) (*phi_slope)(block) = slope;
    }
  }

  const NonlinearLeastSquaresProblem& problem_;
  const Coordinates& coordinates_;
  RobustLoss loss_;
  long residual_count_ = -1, robust_blocks_ = 0;
  int evaluations_ = 0;
  double last_rms_ = 0.0;
};

// ---- The package's Levenberg-Marquardt: the residual problem as a linearised one. --------------

// The loss as iteratively re-weighted least squares: at the current point the Jacobian of the raw
// residuals J (forward differences, one evaluation per free parameter, unless the problem gives
// it), each block's weight w = rho'(|r_b|^2), and the normal equations J^T W J, J^T W r (the
// cost's gradient, with a Gauss-Newton matrix that leaves out the loss's curvature). A step is
// held in the bounds; its residuals become the current ones when it is accepted.
class ReweightedResiduals : public LinearisedLeastSquaresProblem {
 public:
  ReweightedResiduals(CorrectedProblem& problem, const Coordinates& coordinates, const Eigen::VectorXd& z,
                      const Eigen::VectorXd& raw, std::vector<double>* rms_history)
      : problem_(problem), coordinates_(coordinates), z_(z), raw_(raw), rms_history_(rms_history) {}

  bool linearise(double* cost, Eigen::MatrixXd* normal, Eigen::VectorXd* gradient) override {
    Eigen::MatrixXd J;
    if (!problem_.evaluateRaw(z_, &raw_, &J, true)) return false;
    const Eigen::VectorXd w = problem_.weights(raw_);
    *normal = J.transpose() * w.asDiagonal() * J;
    *gradient = J.transpose() * w.cwiseProduct(raw_);
    *cost = problem_.rawCost(raw_);
    return true;
  }
  bool trialCost(const Eigen::VectorXd& step, double* cost) override {
    if (!problem_.evaluateRaw(clamped(z_ + step), &trial_raw_, nullptr)) return false;
    *cost = problem_.rawCost(trial_raw_);
    return true;
  }
  bool accept(const Eigen::VectorXd& step) override {
    z_ = clamped(z_ + step);
    raw_ = trial_raw_;
    rms_history_->push_back(problem_.blockRms(raw_));
    return false;
  }
  const Eigen::VectorXd& coordinates() const { return z_; }
  double cost() const { return problem_.rawCost(raw_); }

 private:
  Eigen::VectorXd clamped(Eigen::VectorXd z) const {
    for (long k = 0; k < z.size(); ++k) z(k) = coordinates_.clamped(k, z(k));
    return z;
  }

  CorrectedProblem& problem_;
  const Coordinates& coordinates_;
  Eigen::VectorXd z_, raw_, trial_raw_;
  std::vector<double>* rms_history_;
};

// ---- Ceres: one cost function over the free coordinates, bounds on the parameter block. -------

class CeresResiduals : public ceres::CostFunction {
 public:
  CeresResiduals(CorrectedProblem* problem, long residuals, long parameters)
      : problem_(problem), parameters_(parameters) {
    set_num_residuals(static_cast<int>(residuals));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(parameters));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::VectorXd z = Eigen::Map<const Eigen::VectorXd>(parameters[0], parameters_);
    const bool want = jacobians != nullptr && jacobians[0] != nullptr;
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    if (!problem_->evaluate(z, &r, want ? &J : nullptr)) return false;
    Eigen::Map<Eigen::VectorXd>(residuals, num_residuals()) = r;
    if (want) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          jacobians[0], num_residuals(), parameters_) = J;
    }
    return true;
  }

 private:
  CorrectedProblem* problem_;
  long parameters_;
};

// Records the blocks' RMS after every accepted step (the last point evaluated), and stops the
// solve after `max_accepted` of them: an iteration is a Jacobian evaluation for both engines
// (Ceres' own cap counts refused steps too, which cost one evaluation each).
class AcceptedSteps : public ceres::IterationCallback {
 public:
  AcceptedSteps(const CorrectedProblem* problem, std::vector<double>* history, int max_accepted)
      : problem_(problem), history_(history), max_accepted_(max_accepted) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (summary.iteration == 0 || !summary.step_is_successful) return ceres::SOLVER_CONTINUE;
    history_->push_back(problem_->lastRms());
    if (++accepted_ < max_accepted_) return ceres::SOLVER_CONTINUE;
    capped_ = true;
    return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  int accepted() const { return accepted_; }
  bool capped() const { return capped_; }

 private:
  const CorrectedProblem* problem_;
  std::vector<double>* history_;
  int max_accepted_, accepted_ = 0;
  bool capped_ = false;
};

void solveWithCeres(CorrectedProblem& corrected, const Coordinates& coordinates, Eigen::VectorXd& z,
                    const NonlinearLeastSquaresOptions& options, NonlinearLeastSquaresReport* report) {
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  CeresResiduals cost(&corrected, corrected.residualCount(), z.size());
  problem.AddResidualBlock(&cost, nullptr, z.data());
  for (long k = 0; k < z.size(); ++k) {
    if (std::isfinite(coordinates.lower(k))) problem.SetParameterLowerBound(z.data(), static_cast<int>(k), coordinates.lower(k));
    if (std::isfinite(coordinates.upper(k))) problem.SetParameterUpperBound(z.data(), static_cast<int>(k), coordinates.upper(k));
  }
  ceres::Solver::Options solver;
  solver.minimizer_type = ceres::TRUST_REGION;
  solver.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver.linear_solver_type = ceres::DENSE_QR;
  // The cap is on accepted steps (AcceptedSteps); this one only bounds refused steps.
  solver.max_num_iterations = 10 * options.max_iterations;
  // The damping a hand-written Levenberg-Marquardt starts with (1e-2 of the diagonal), not Ceres'
  // nearly undamped 1e4: the stabiliser's cost is clipped by its stroke, and Gauss-Newton steps
  // from afar are refused one by one.
  solver.initial_trust_region_radius = 1e2;
  solver.function_tolerance = options.function_tolerance;
  solver.parameter_tolerance = options.parameter_tolerance;
  solver.gradient_tolerance = options.gradient_tolerance;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  solver.minimizer_progress_to_stdout = false;
  // The parameter block holds the last accepted point even if an evaluation fails later.
  solver.update_state_every_iteration = true;
  AcceptedSteps steps(&corrected, &report->rms_history, options.max_iterations);
  solver.callbacks.push_back(&steps);
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  report->iterations = steps.accepted();
  report->message = "ceres: " + summary.message;
  if (steps.capped()) {
    report->termination = SolverTermination::kIterationLimit;
    report->message = "ceres: " + std::to_string(options.max_iterations) + " accepted steps";
    return;
  }
  switch (summary.termination_type) {
    case ceres::CONVERGENCE:
      report->termination = SolverTermination::kConverged;
      break;
    case ceres::NO_CONVERGENCE:
      report->termination = SolverTermination::kIterationLimit;
      break;
    default:
      report->termination = SolverTermination::kFailed;
  }
}

// ---- Eigen's MINPACK port: lmder, one outer iteration (one Jacobian) per minimizeOneStep. ------

struct MinpackFunctor {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;

  CorrectedProblem* problem;
  long n, m;
  int inputs() const { return static_cast<int>(n); }
  int values() const { return static_cast<int>(m); }
  // MINPACK has no "cannot evaluate here": such a point gets a cost far above any other, so the
  // step to it is refused and the trust region shrinks.
  int operator()(const Eigen::VectorXd& z, Eigen::VectorXd& fvec) const {
    if (!problem->evaluate(z, &fvec, nullptr)) fvec.setConstant(m, 1e100);
    return 0;
  }
  int df(const Eigen::VectorXd& z, Eigen::MatrixXd& fjac) const {
    Eigen::VectorXd r;
    return problem->evaluate(z, &r, &fjac) ? 0 : -1;
  }
};

void solveWithEigen(CorrectedProblem& corrected, const Coordinates& coordinates, Eigen::VectorXd& z,
                    const NonlinearLeastSquaresOptions& options, NonlinearLeastSquaresReport* report) {
  MinpackFunctor functor{&corrected, z.size(), corrected.residualCount()};
  if (functor.m < functor.n) {
    report->termination = SolverTermination::kFailed;
    report->message = "eigen: fewer residuals than free parameters";
    return;
  }
  Eigen::LevenbergMarquardt<MinpackFunctor> lm(functor);
  lm.parameters.ftol = options.function_tolerance;
  lm.parameters.xtol = options.parameter_tolerance;
  lm.parameters.gtol = options.gradient_tolerance;
  lm.parameters.maxfev = 1000000;  // the iteration cap below is the limit
  namespace S = Eigen::LevenbergMarquardtSpace;
  S::Status status = lm.minimizeInit(z);
  int iterations = 0;
  double fnorm = lm.fnorm;
  while (status == S::NotStarted || status == S::Running) {
    if (iterations >= options.max_iterations) break;
    status = lm.minimizeOneStep(z);
    ++iterations;
    if (lm.fnorm < fnorm) {
      fnorm = lm.fnorm;
      // minimizeOneStep ends on the accepted point's evaluation.
      report->rms_history.push_back(corrected.lastRms());
    }
  }
  for (long k = 0; k < z.size(); ++k) z(k) = coordinates.clamped(k, z(k));
  report->iterations = iterations;
  static const char* const kWhy[] = {
      "improper input parameters",
      "the relative cost reduction is at most function_tolerance",
      "the relative step is at most parameter_tolerance",
      "the relative cost reduction and step are both at their tolerances",
      "the gradient is orthogonal to the residuals (gradient_tolerance)",
      "too many function evaluations",
      "function_tolerance is too small: no further reduction is possible",
      "parameter_tolerance is too small: no further improvement of the solution is possible",
      "gradient_tolerance is too small: the gradient cannot get smaller",
      "the Jacobian could not be evaluated at the accepted point"};
  const int code = static_cast<int>(status);
  report->message = std::string("eigen: ") +
                    (code >= 0 && code <= 9 ? kWhy[code]
                                            : std::to_string(options.max_iterations) + " accepted steps");
  switch (status) {
    case S::NotStarted:
    case S::Running:
      report->termination = SolverTermination::kIterationLimit;
      break;
    case S::RelativeReductionTooSmall:
    case S::RelativeErrorTooSmall:
    case S::RelativeErrorAndReductionTooSmall:
    case S::CosinusTooSmall:
      report->termination = SolverTermination::kConverged;
      break;
    case S::TooManyFunctionEvaluation:
      report->termination = SolverTermination::kIterationLimit;
      break;
    case S::FtolTooSmall:
    case S::XtolTooSmall:
    case S::GtolTooSmall:
      report->termination = SolverTermination::kNoProgress;
      break;
    default:
      report->termination = SolverTermination::kFailed;
  }
}

void checkProblem(const NonlinearLeastSquaresProblem& problem, const Eigen::VectorXd& start) {
  if (!problem.residuals) throw std::invalid_argument("nonlinear least squares: no residual functor");
  if (problem.block_size < 1)
    throw std::invalid_argument("nonlinear least squares: block_size must be >= 1");
  if (start.size() != static_cast<long>(problem.parameters.size()))
    throw std::invalid_argument("nonlinear least squares: " + std::to_string(start.size()) +
                                " start values for " + std::to_string(problem.parameters.size()) +
                                " parameters");
  for (std::size_t j = 0; j < problem.parameters.size(); ++j) {
    const SolverParameter& p = problem.parameters[j];
    const std::string name = "nonlinear least squares: parameter '" + p.name + "': ";
    if (!(p.lower <= p.upper)) throw std::invalid_argument(name + "lower bound above the upper");
    if (p.logarithmic && !(p.lower > 0.0))
      throw std::invalid_argument(name + "a logarithmic parameter needs a positive lower bound");
    if (!(p.difference_step > 0.0)) throw std::invalid_argument(name + "difference_step must be > 0");
    if (!std::isfinite(start(static_cast<long>(j))))
      throw std::invalid_argument(name + "the start value is not finite");
  }
}

}  // namespace

NonlinearLeastSquaresReport minimiseLevenbergMarquardt(LinearisedLeastSquaresProblem& problem,
                                                       const NonlinearLeastSquaresOptions& options) {
  const std::string option_problem = options.validate();
  if (!option_problem.empty())
    throw std::invalid_argument("nonlinear least squares: " + option_problem);
  const double cpu_start = processCpuSeconds();
  const DampingSchedule& schedule = options.damping;
  NonlinearLeastSquaresReport report;
  report.termination = SolverTermination::kIterationLimit;
  report.message = std::to_string(options.max_iterations) + " accepted steps";
  double lambda = schedule.initial;
  double cost = 0.0;
  Eigen::MatrixXd normal;
  Eigen::VectorXd gradient;
  for (bool first = true; report.iterations < options.max_iterations; first = false) {
    if (!problem.linearise(&cost, &normal, &gradient)) {
      // Past the start, the accepted point stands: no step can be taken from it.
      report.termination = first ? SolverTermination::kFailed : SolverTermination::kNoProgress;
      report.message = first ? "the model cannot be evaluated at the start"
                             : "the model cannot be linearised at the accepted point";
      break;
    }
    if (first) report.initial_cost = cost;
    report.final_cost = cost;
    if (!(gradient.lpNorm<Eigen::Infinity>() > 0.0)) {
      report.termination = SolverTermination::kConverged;
      report.message = "the gradient is zero";
      break;
    }
    bool accepted = false, converged = false;
    double relative = 0.0;
    for (int attempt = 0; attempt < schedule.attempts && !accepted; ++attempt) {
      Eigen::MatrixXd damped = normal;
      // The floor keeps a parameter without effect (a zero column) from an undamped solve.
      damped.diagonal() += lambda * (normal.diagonal().array() + 1e-9).matrix();
      const Eigen::VectorXd step = damped.ldlt().solve(-gradient);
      double trial = 0.0;
      if (step.allFinite() && problem.trialCost(step, &trial) && trial < cost) {
        accepted = true;
        ++report.iterations;
        converged = problem.accept(step);
        relative = (cost - trial) / std::max(cost, 1e-300);
        cost = report.final_cost = trial;
        lambda = std::max(lambda / schedule.decrease, schedule.minimum);
      } else {
        lambda *= schedule.increase;
      }
    }
    if (!accepted) {
      report.termination = SolverTermination::kNoProgress;
      report.message = "no step lowers the cost (" + std::to_string(schedule.attempts) + " tried)";
      break;
    }
    if (converged || relative < options.function_tolerance) {
      report.termination = SolverTermination::kConverged;
      report.message = converged ? "the problem's own test" : "the relative cost reduction is below function_tolerance";
      break;
    }
  }
  report.message = std::string("levenberg_marquardt: ") + report.message;
  report.cpu_s = processCpuSeconds() - cpu_start;
  return report;
}

NonlinearLeastSquaresReport solveNonlinearLeastSquares(const NonlinearLeastSquaresProblem& problem,
                                                       const Eigen::VectorXd& start,
                                                       const NonlinearLeastSquaresOptions& options) {
  const std::string option_problem = options.validate();
  if (!option_problem.empty())
    throw std::invalid_argument("nonlinear least squares: " + option_problem);
  checkProblem(problem, start);
  const double cpu_start = processCpuSeconds();
  const Coordinates coordinates(problem.parameters, start);
  CorrectedProblem corrected(problem, coordinates, options.loss);
  NonlinearLeastSquaresReport report;
  Eigen::VectorXd z = coordinates.startCoordinates();
  report.values = coordinates.values(z);
  Eigen::VectorXd raw, r;
  if (!corrected.evaluateRaw(z, &raw, nullptr)) {
    report.termination = SolverTermination::kFailed;
    report.message = "the model cannot be evaluated at the start";
    report.residual_evaluations = corrected.evaluations();
    report.cpu_s = processCpuSeconds() - cpu_start;
    return report;
  }
  report.initial_cost = corrected.rawCost(raw);
  if (coordinates.size() == 0) {
    report.final_cost = report.initial_cost;
    report.termination = SolverTermination::kConverged;
    report.message = "no free parameter";
  } else if (options.engine == SolverEngine::kLevenbergMarquardt) {
    ReweightedResiduals linearised(corrected, coordinates, z, raw, &report.rms_history);
    const NonlinearLeastSquaresReport steps = minimiseLevenbergMarquardt(linearised, options);
    report.iterations = steps.iterations;
    report.termination = steps.termination;
    report.message = steps.message;
    z = linearised.coordinates();
    report.values = coordinates.values(z);
    report.final_cost = linearised.cost();  // the accepted point's own evaluation
  } else {
    if (options.engine == SolverEngine::kCeres)
      solveWithCeres(corrected, coordinates, z, options, &report);
    else
      solveWithEigen(corrected, coordinates, z, options, &report);
    report.values = coordinates.values(z);
    // The final cost, evaluated at the values returned (not counted as the engine's work).
    if (corrected.evaluate(z, &r, nullptr)) report.final_cost = CorrectedProblem::cost(r);
    else report.termination = SolverTermination::kFailed;
  }
  report.residual_evaluations = corrected.evaluations();
  for (long k = 0; k < coordinates.size(); ++k) {
    const double zk = coordinates.clamped(k, z(k));
    const double span = 1e-9 * std::max(1.0, std::abs(zk));
    if (zk <= coordinates.lower(k) + span || zk >= coordinates.upper(k) - span)
      report.on_bound.push_back(coordinates.parameter(k).name);
  }
  report.cpu_s = processCpuSeconds() - cpu_start;
  return report;
}

RobustRidgeRegression::RobustRidgeRegression(long feature_count, long output_count, RobustLoss loss)
    : loss_(loss),
      normal_(Eigen::MatrixXd::Zero(feature_count, feature_count)),
      right_(Eigen::MatrixXd::Zero(feature_count, output_count)) {
  const std::string problem = loss.validate();
  if (!problem.empty()) throw std::invalid_argument("robust ridge regression: " + problem);
  if (feature_count < 1 || output_count < 1)
    throw std::invalid_argument("robust ridge regression: needs at least one feature and one output");
}

void RobustRidgeRegression::add(const Eigen::VectorXd& features, const Eigen::VectorXd& target,
                                double data_weight, double reference_residual_norm) {
  if (features.size() != normal_.rows() || target.size() != right_.cols())
    throw std::invalid_argument("robust ridge regression: an observation of the wrong size");
  const double w = std::max(0.0, data_weight) *
                   loss_.weight(reference_residual_norm * reference_residual_norm);
  normal_.noalias() += w * features * features.transpose();
  right_.noalias() += w * features * target.transpose();
  ++count_;
}

bool RobustRidgeRegression::solve(double ridge, Eigen::MatrixXd* coefficients,
                                  const Eigen::MatrixXd* prior) const {
  if (count_ == 0) return false;
  if (!(ridge >= 0.0)) throw std::invalid_argument("robust ridge regression: ridge must be >= 0");
  const double floor = 1e-12 * std::max(1e-300, normal_.diagonal().maxCoeff());
  const Eigen::VectorXd penalty = (ridge * normal_.diagonal()).array() + floor;
  Eigen::MatrixXd A = normal_;
  A.diagonal() += penalty;
  Eigen::MatrixXd B = right_;
  if (prior) {
    if (prior->rows() != right_.rows() || prior->cols() != right_.cols())
      throw std::invalid_argument("robust ridge regression: the prior has the wrong size");
    B += penalty.asDiagonal() * (*prior);
  }
  const Eigen::MatrixXd solution = A.ldlt().solve(B);
  if (!solution.allFinite()) return false;
  *coefficients = solution;
  return true;
}

}  // namespace deep_ois
