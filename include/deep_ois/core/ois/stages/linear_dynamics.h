// The linear-dynamics stage's values (src/core/ois/stages/linear_dynamics_stage.cpp): raw command
// += focal_px * coefficients * the state of an orthonormal basis of the three gyro axes
// (core/ois/linear_dynamics_basis.h).
#pragma once

#include <Eigen/Core>

#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LinearDynamicsValues : StageValuesOf<LinearDynamicsValues> {
  static constexpr const char* kStage = "linear_dynamics";
  LinearDynamicsBasisSpec basis;
  Eigen::MatrixXd coefficients;  // 2 x 3 basis.order (focal units per basis state); empty = off
  bool active() const { return coefficients.size() != 0; }
};

}  // namespace deep_ois
