// The linear residual stage's values (src/core/ois/stages/linear_residual_stage.cpp).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LinearResidualValues : StageValuesOf<LinearResidualValues> {
  static constexpr const char* kStage = "linear_residual";
  // shift += focal_px * residual * the bank of leaky rate integrals with these time constants
  // (the K integrals of rate x, then the K of rate y). Empty = none.
  std::vector<double> residual_time_constants_s;
  Eigen::MatrixXd residual;  // 2 x (2 * K), unitless (radians of the leaky integral to focal units)
};

}  // namespace deep_ois
