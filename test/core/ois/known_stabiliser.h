// A stabiliser with every usual part (gain, centring high-pass, actuator, sensor lag, stroke) and
// known values: the truth the stabiliser model's tests (and the frame-pair processor's) run on.
#pragma once

#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {

inline StabiliserModel knownStabiliser() {
  StabiliserModel p;
  p.get<CentringValues>().gain << 0.0, 0.9, -1.05, 0.0;
  p.get<CentringValues>().highpass_corner_hz = 0.8;
  p.get<ActuatorValues>().actuator_natural_hz = 30.0;
  p.get<ActuatorValues>().actuator_damping = 0.6;
  p.get<ActuatorValues>().sensor_lag_s = 0.002;
  p.get<StrokeValues>().stroke_x_deg = 0.8;
  p.get<StrokeValues>().stroke_y_deg = 1.2;
  return p;
}

}  // namespace deep_ois
