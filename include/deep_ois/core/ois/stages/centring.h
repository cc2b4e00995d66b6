// The centring stage's values (src/core/ois/stages/centring_stage.cpp).
#pragma once

#include <Eigen/Core>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct CentringValues : StageValuesOf<CentringValues> {
  static constexpr const char* kStage = "centring";
  // Commanded shift = focal_px * gain * (tan theta_x, tan theta_y) for the high-passed pan/tilt
  // angles theta (rad, camera optical frame). An ideal stabiliser of this package's convention has
  // gain = [[0, 1], [-1, 0]] (x follows the turn about y, y against the turn about x); a module
  // cancelling 90 % of the motion has 0.9 of that; a mount turned in the image plane mixes axes.
  Eigen::Matrix2d gain = (Eigen::Matrix2d() << 0.0, 1.0, -1.0, 0.0).finished();
  double highpass_corner_hz = 0.6;  // the integrated angle leaks back with this corner
};

}  // namespace deep_ois
