// The stroke stage's values (src/core/ois/stages/stroke_stage.cpp).
#pragma once

#include <Eigen/Core>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct StrokeValues : StageValuesOf<StrokeValues> {
  static constexpr const char* kStage = "stroke";
  double stroke_x_deg = 1.0;  // commanded shift limits, as angles (f tan(limit) pixels)
  double stroke_y_deg = 1.0;
  bool circular_stroke = false;  // false: a box of the two limits; true: the ellipse inside it
  // A soft stroke: the command u becomes stroke * tanh(u / stroke) (per axis for the box, radially
  // for the ellipse) instead of stopping at the stroke. Exclusive with anti_windup (a soft stroke
  // is never met, so there is no angle to hold).
  bool soft_stroke = false;
  // The integrated angle at the end stop. false: it keeps integrating beyond the stroke; true
  // (anti-windup): it is held where the command meets the stroke, so the lens leaves the stroke as
  // soon as the rate turns (the Pixel 4's log, docs/stabiliser_model.md).
  bool anti_windup = false;
};

// The stroke's limits in pixels (f tan(limit)): the command's limit and the lens' end stop.
Eigen::Vector2d strokePx(const StrokeValues& stroke, double focal_px);
// The model's stroke stage's limits in pixels; its defaults' in a model without one.
Eigen::Vector2d strokePx(const StabiliserModel& model, double focal_px);

}  // namespace deep_ois
