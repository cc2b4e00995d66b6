// The actuator stage's values (src/core/ois/stages/actuator_stage.cpp).
#pragma once

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct ActuatorValues : StageValuesOf<ActuatorValues> {
  static constexpr const char* kStage = "actuator";
  double actuator_natural_hz = 35.0;
  double actuator_damping = 0.7;
  double sensor_lag_s = 0.0;  // the position loop acts on commands this old (Hall sensor delay)
};

}  // namespace deep_ois
