// A stabiliser with every usual part (gain, centring high-pass, actuator, sensor lag, stroke) and
// known values: the truth the stabiliser model's tests (and the frame-pair processor's) run on.
#pragma once

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

inline StabiliserParameters knownStabiliser() {
  StabiliserParameters p;
  p.gain << 0.0, 0.9, -1.05, 0.0;
  p.highpass_corner_hz = 0.8;
  p.actuator_natural_hz = 30.0;
  p.actuator_damping = 0.6;
  p.sensor_lag_s = 0.002;
  p.stroke_x_deg = 0.8;
  p.stroke_y_deg = 1.2;
  return p;
}

}  // namespace deep_ois
