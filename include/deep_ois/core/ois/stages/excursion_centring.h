// The excursion re-centring stage's values (src/core/ois/stages/excursion_centring_stage.cpp).
#pragma once

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct ExcursionCentringValues : StageValuesOf<ExcursionCentringValues> {
  static constexpr const char* kStage = "excursion_centring";
  // The centring corner is highpass_corner_hz * (1 + k e^2), e^2 = (u_x / stroke_x)^2 +
  // (u_y / stroke_y)^2 for the command u before the stroke limit (e = 1 on the stroke). 0 = off.
  double excursion_centring = 0.0;
};

}  // namespace deep_ois
