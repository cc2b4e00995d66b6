// The learned residual stage's values (src/core/ois/stages/learned_residual_stage.cpp).
#pragma once

#include <Eigen/Core>
#include <string>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LearnedResidualValues : StageValuesOf<LearnedResidualValues> {
  static constexpr const char* kStage = "learned_residual";
  // shift += focal_px * nonlinear_residual * features, the features a named set of functions of
  // the chain's own state (nonlinearFeatureCount). Empty name = none.
  std::string nonlinear_features;
  Eigen::MatrixXd nonlinear_residual;  // 2 x nonlinearFeatureCount(nonlinear_features)
};

}  // namespace deep_ois
