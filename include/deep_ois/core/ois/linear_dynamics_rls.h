// Recursive least squares with exponential forgetting on the linear-dynamics stage's coefficients
// (stages/linear_dynamics_stage.cpp), the rest of the chain held: what the online learner adapts
// between the solver's refits of the whole chain (core/online/online_stabiliser_learner.h).
//
// Why: inside the stroke the lens motion is linear in the stage's coefficients C (2 x n, n = 3 x
// the basis' order), motion_i = J_i C + (what the other stages move), so each new lens motion the
// images give is one row of a linear least squares. The recursive form absorbs rows one at a
// time at O(n^2) each, with no buffer of past rows; the forgetting lets the estimate follow a
// stabiliser whose response drifts (temperature, a focus change) and lets evidence older than the
// memory go.
//
// Per image axis a (row a of C, its own regressor rows: a coupled mount moves both), one sample
// (regressor phi, target y, weight w, stamp t):
//   P <- P / lambda^(t - t_last)          (forgetting per second of stamps; not beyond the start's P)
//   k  = P phi / (1 / w' + phi^T P phi),  w' = w x Huber(|y - C phi|, huber_px)
//   C_a <- C_a + k (y - phi^T C_a),  P <- P - k phi^T P.
// With lambda = 1 it is the exact least squares of every row with the start as a ridge prior of
// weight P0^-1. P0^-1 = prior_lens_motions x the mean weighted energy of each column in the first
// evidence given (so the prior is worth that many lens motions whatever the basis' scale).
// Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

struct LinearDynamicsRlsOptions {
  // The weight left to a lens motion one second old (of the samples' stamps), in (0, 1]; 1: no
  // forgetting. Memory about 1 / (1 - factor) seconds (0.98: 50 s).
  double forgetting_per_s = 0.98;
  // What the starting coefficients are worth, in lens motions of the first evidence (a ridge
  // towards them); > 0.
  double prior_lens_motions = 20.0;
  double huber_px = 0.3;  // Huber threshold on a sample's residual norm, pixels (as the fit's)

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// The lens motions of recordings as rows of the coefficients' least squares, linearised about the
// model's coefficients C0: for each usable observation (predicted by the chain, finite), the
// motion's derivative along each coefficient column per image axis (J_x, J_y rows: n each, px per
// focal unit) and the target motion_px - predicted(C0) + J C0 (what C should reproduce). Exact
// inside the stroke. One run of the chain per coefficient column, plus one.
struct LinearDynamicsEvidence {
  Eigen::MatrixXd along_x, along_y;  // m x n
  Eigen::MatrixXd targets;           // m x 2, pixels
  Eigen::VectorXd weights;           // m, the observations' (>= 0)
  Eigen::VectorXd residual_px;       // m, |motion - predicted(C0)|: the Huber weights' residual
  Eigen::VectorXd stamps_s;          // m, each observation's t_b (IMU clock)
  long rows() const { return targets.rows(); }
};

// Throws std::invalid_argument when the model has no active linear-dynamics stage.
// Defined beside the stage (stages/linear_dynamics_stage.cpp).
LinearDynamicsEvidence linearDynamicsEvidence(const StabiliserModel& model,
                                              const std::vector<StabiliserFitRecording>& recordings,
                                              const StabiliserFitOptions& options);

class LinearDynamicsRls {
 public:
  // Starts from `coefficients` (2 x n, finite). Throws std::invalid_argument naming the problem
  // (bad options, a matrix of another shape).
  LinearDynamicsRls(const Eigen::MatrixXd& coefficients, const LinearDynamicsRlsOptions& options);

  // Absorbs the evidence's rows in the order of their stamps. Rows of zero weight or non-finite
  // values are skipped (counted). Throws std::invalid_argument when the evidence's columns are not
  // the coefficients'.
  void add(const LinearDynamicsEvidence& evidence);
  // New coefficients from elsewhere (the solver's refit of the whole chain), the confidence kept:
  // later rows move them as they moved these.
  void rebase(const Eigen::MatrixXd& coefficients);

  const Eigen::MatrixXd& coefficients() const { return coefficients_; }
  std::size_t samples() const { return samples_; }  // rows absorbed
  std::size_t skipped() const { return skipped_; }  // rows skipped (no weight, not finite)
  // Per image axis, the covariance factor P (n x n) (for tests and diagnostics).
  const Eigen::MatrixXd& covariance(int axis) const { return p_[axis]; }

 private:
  void start(const LinearDynamicsEvidence& evidence);  // P0 from the first evidence's energy

  LinearDynamicsRlsOptions options_;
  Eigen::MatrixXd coefficients_;
  Eigen::MatrixXd p_[2];
  double p0_trace_[2] = {0.0, 0.0};  // forgetting never makes P less certain than the prior
  bool started_ = false;
  double last_stamp_s_ = 0.0;
  std::size_t samples_ = 0, skipped_ = 0;
};

}  // namespace deep_ois
