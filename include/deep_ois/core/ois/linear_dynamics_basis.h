// A linear dynamics of free order from the three gyro axes to the lens: an orthonormal basis of
// filters of the camera's rate (Laguerre, or a two-pole generalised orthonormal basis), whose
// states a 2 x size() matrix maps to the lens command, in focal-length units (tan-angle).
//
// Why: a stabiliser that estimates the intended motion (a constant-velocity Kalman filter, an
// alpha-beta tracker, a velocity loop, a second-order centring) is, in steady state and inside its
// stroke, a linear filter of its gyro, of an order no fixed chain names. Any stable strictly proper
// filter with poles near the basis' poles is a short combination of its functions, and the lens is
// linear in the combination's coefficients, so the fit is a weighted ridge least squares in closed
// form (fitLinearDynamicsCoefficients) when the rest of the chain (a stroke after it) is held.
//
// The basis, per gyro axis (continuous time, poles p_k = 2 pi pole_hz in rad/s):
//   F_1(s) = sqrt(2 p_1) / (s + p_1),
//   F_k(s) = sqrt(2 p_k) / (s + p_k) * prod_{j<k} (s - p_j) / (s + p_j),
// orthonormal in L2 (for a white rate, the states are uncorrelated with unit variance per unit
// spectral density). All poles equal (second_pole_hz = 0): the Laguerre basis. With a second pole
// the functions alternate between the two (a slow centring pole beside a fast actuator pole).
// Realised as x' = A x + B u per axis (A lower triangular), discretised exactly for a rate held
// over one step of the predictor (as the model's leaky integrators are): x <- Ad x + Bd u.
// Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace deep_ois {

struct LinearDynamicsBasisSpec {
  double pole_hz = 1.0;  // the basis' pole (a corner), Hz; > 0
  int order = 8;         // basis functions per gyro axis (state size 3 x order), >= 1
  // A second pole, Hz (0 = none: the Laguerre basis). With one, function k (from 1) has
  // pole_hz when k is odd and second_pole_hz when k is even.
  double second_pole_hz = 0.0;
  // Non-empty: instead of the Laguerre chain, a bank of independent first-order low-passes, the
  // leaky integrals y' = u - y / tau of the rate (state in rad), one per time constant (seconds);
  // order is then their count. The form older model files' residual banks convert to exactly.
  std::vector<double> time_constants_s;

  // Empty when usable; otherwise a sentence naming the bad field. step_s is the step the basis
  // will be discretised at (a pole above 0.5 / step_s, past the step's Nyquist rate, is refused).
  std::string validate(double step_s) const;
  // The pole of function k (0-based), rad/s.
  double poleRadS(int k) const;
  bool firstOrder() const { return !time_constants_s.empty(); }
  bool operator==(const LinearDynamicsBasisSpec& other) const {
    return pole_hz == other.pole_hz && order == other.order && second_pole_hz == other.second_pole_hz &&
           time_constants_s == other.time_constants_s;
  }
};

class LinearDynamicsBasis {
 public:
  // Throws std::invalid_argument with the validate() sentence, or for a step that is not
  // positive and finite.
  LinearDynamicsBasis(const LinearDynamicsBasisSpec& spec, double step_s);

  // The state of a stabiliser switched on: zero (the filters at rest).
  void reset();
  // One step with the camera-frame rate (rad/s) held over it; returns the new state.
  const Eigen::VectorXd& advance(const Eigen::Vector3d& rate_rad_s);
  // The state, axis-major: functions 1..order of the x rate, then of y, then of z
  // (units: rad/s x sqrt(s), the basis' normalisation).
  const Eigen::VectorXd& state() const { return state_; }
  int size() const { return static_cast<int>(state_.size()); }
  int order() const { return spec_.order; }
  double stepS() const { return step_s_; }
  const LinearDynamicsBasisSpec& spec() const { return spec_; }

  // The per-axis realisation: continuous (A, B) and its exact discretisation (Ad, Bd).
  const Eigen::MatrixXd& continuousA() const { return a_; }
  const Eigen::VectorXd& continuousB() const { return b_; }
  const Eigen::MatrixXd& discreteA() const { return ad_; }
  const Eigen::VectorXd& discreteB() const { return bd_; }

 private:
  LinearDynamicsBasisSpec spec_;
  double step_s_;
  Eigen::MatrixXd a_, ad_;
  Eigen::VectorXd b_, bd_;
  Eigen::VectorXd state_;
  Eigen::VectorXd next_;  // scratch of advance(), one axis' next state
};

// The basis run over a gyro stream the way LensShiftPredictor runs its chain: internal steps of
// step_s from the first sample, the rate interpolated linearly at each step's middle and held over
// the step; the state at each of `times_s` interpolated linearly between the steps around it (held
// at the first and last step outside them). stamps_s strictly increasing, the same count as
// rates_rad_s (rad/s, camera frame). Returns times_s.size() x basis size. Throws
// std::invalid_argument naming the problem (sizes, order of stamps, non-finite values).
Eigen::MatrixXd linearDynamicsStates(const LinearDynamicsBasisSpec& spec, double step_s,
                                     const std::vector<double>& stamps_s,
                                     const std::vector<Eigen::Vector3d>& rates_rad_s,
                                     const std::vector<double>& times_s);

// What a fit saw, beside its coefficients.
struct LinearDynamicsFitReport {
  int samples = 0;            // rows with a positive weight
  int unexcited_states = 0;   // state components with no weighted energy: coefficient 0
  double weighted_rms = 0.0;  // of the fitted residual, target units (per component)
};

// The coefficients C (2 x states.cols()) minimising
//   sum_i w_i |targets_i - C states_i|^2 + ridge * sum_j G_jj |C_:,j|^2,
// G_jj = sum_i w_i states_ij^2 (the ridge is relative to each state component's weighted energy,
// so it does not depend on the basis' scaling; ridge 0: plain least squares). Rows are samples:
// `states` N x size (LinearDynamicsBasis::state() or differences of them), `targets` N x 2 (the
// lens command in focal units, or the matching differences), `weights` N non-negative (empty: all
// 1). A state component with no weighted energy (a gyro axis that never moved) gets coefficient 0
// and is counted in the report. Solved by a Householder QR of the scaled, stacked system.
// Throws std::invalid_argument naming the bad input: mismatched sizes, a non-finite value (its
// row), a negative weight, a negative or non-finite ridge, fewer weighted samples than excited
// state components, or (ridge 0) a rank-deficient system.
Eigen::MatrixXd fitLinearDynamicsCoefficients(const Eigen::MatrixXd& states, const Eigen::MatrixXd& targets,
                                              const Eigen::VectorXd& weights, double ridge,
                                              LinearDynamicsFitReport* report = nullptr);

}  // namespace deep_ois
