// The pan detection stage's values (src/core/ois/stages/pan_detection_stage.cpp).
#pragma once

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct PanDetectionValues : StageValuesOf<PanDetectionValues> {
  static constexpr const char* kStage = "pan_detection";
  // While the low-passed |pan/tilt rate| exceeds the threshold (0 = off) the stabiliser re-centres
  // with pan_release_corner_hz; below 0.7 x the threshold it holds again.
  double pan_detection_rate_rad_s = 0.0;
  double pan_detection_time_constant_s = 0.1;
  double pan_release_corner_hz = 5.0;
};

}  // namespace deep_ois
