// The linear-dynamics stage's values (src/core/ois/stages/linear_dynamics_stage.cpp): raw command
// (or, with output_to_lens, the lens after the whole chain) += focal_px * coefficients * the state
// of a basis of filters of the three gyro axes (core/ois/linear_dynamics_basis.h).
#pragma once

#include <Eigen/Core>

#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LinearDynamicsValues : StageValuesOf<LinearDynamicsValues> {
  static constexpr const char* kStage = "linear_dynamics";
  LinearDynamicsBasisSpec basis;
  Eigen::MatrixXd coefficients;  // 2 x 3 basis.order (focal units per basis state); empty = off
  // Where it adds: the raw command before the stroke (false), or the lens after the last stage,
  // past the stroke and the actuator (true: the form older files' residual banks convert to).
  bool output_to_lens = false;
  bool active() const { return coefficients.size() != 0; }
  // The same basis and output (coefficients aside): what one recursive least squares can adapt.
  bool sameForm(const LinearDynamicsValues& other) const {
    return basis == other.basis && output_to_lens == other.output_to_lens;
  }
};

}  // namespace deep_ois
