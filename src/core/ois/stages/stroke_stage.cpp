// The stroke stage: how far the lens can travel (a box of two limits or the ellipse inside it, as
// angles) and what happens at the end: an end stop, or a soft stroke (stroke * tanh(command /
// stroke)); with an end stop, an integrator that winds up beyond it or is held there (anti-windup).
#include <yaml-cpp/yaml.h>

#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"

namespace deep_ois {

const StabiliserStage& strokeStage() {
  static const StabiliserStage stage{
      "stroke",
      "the command is limited to the stroke (a box of two limits as angles, or the ellipse inside "
      "it), at an end stop or softly (tanh); at an end stop the integrator winds up or is held "
      "(anti-windup)",
      true,
      {{"stroke_x_deg", "stroke x", "deg", true, 0.02, 20.0, 1e-3, "",
        [](const StabiliserParameters& p) { return p.stroke_x_deg; },
        [](StabiliserParameters* p, double value) { p->stroke_x_deg = value; }, nullptr},
       {"stroke_y_deg", "stroke y", "deg", true, 0.02, 20.0, 1e-3, "",
        [](const StabiliserParameters& p) { return p.stroke_y_deg; },
        [](StabiliserParameters* p, double value) { p->stroke_y_deg = value; }, nullptr}},
      {"stroke_x_deg", "stroke_y_deg", "circular_stroke", "soft_stroke", "anti_windup"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        out << YAML::Key << "stroke_x_deg" << YAML::Value << p.stroke_x_deg;
        out << YAML::Key << "stroke_y_deg" << YAML::Value << p.stroke_y_deg;
        out << YAML::Key << "circular_stroke" << YAML::Value << p.circular_stroke;
        // Optional (written only when used): files without them, every model before these
        // mechanisms, load as a winding-up integrator with an end stop.
        if (p.soft_stroke) out << YAML::Key << "soft_stroke" << YAML::Value << p.soft_stroke;
        if (p.anti_windup) out << YAML::Key << "anti_windup" << YAML::Value << p.anti_windup;
      },
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::optional;
        using stabiliser_file_fields::required;
        p->stroke_x_deg = required<double>(s, "stroke_x_deg");
        p->stroke_y_deg = required<double>(s, "stroke_y_deg");
        p->circular_stroke = required<bool>(s, "circular_stroke");
        p->soft_stroke = optional<bool>(s, "soft_stroke", false);
        p->anti_windup = optional<bool>(s, "anti_windup", false);
      },
      [](const StabiliserParameters& p) {
        std::ostringstream why;
        if (!(p.stroke_x_deg > 0.0 && p.stroke_x_deg < 45.0) ||
            !(p.stroke_y_deg > 0.0 && p.stroke_y_deg < 45.0)) {
          why << "stroke_x_deg, stroke_y_deg: must be in (0, 45) degrees (got " << p.stroke_x_deg
              << ", " << p.stroke_y_deg << ")";
        } else if (p.soft_stroke && p.anti_windup) {
          why << "soft_stroke, anti_windup: one or the other (a soft stroke is never met, so there "
                 "is no angle for anti-windup to hold)";
        }
        return why.str();
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
