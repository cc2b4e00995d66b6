// The actuator coupling stage's values (src/core/ois/stages/actuator_coupling_stage.cpp).
#pragma once

#include <Eigen/Core>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct ActuatorCouplingValues : StageValuesOf<ActuatorCouplingValues> {
  static constexpr const char* kStage = "actuator_coupling";
  // The image shift is (a_x + c_xy a_y, a_y + c_yx a_x) for the actuator's output a and
  // actuator_coupling = (c_xy, c_yx). 0 = none.
  Eigen::Vector2d actuator_coupling = Eigen::Vector2d::Zero();
};

}  // namespace deep_ois
