// The stroke stage: how far the lens can travel (a box of two limits or the ellipse inside it, as
// angles) and what happens at the end: an end stop, or a soft stroke (stroke * tanh(command /
// stroke)); with an end stop, an integrator that winds up beyond it or is held there (anti-windup).
#include <yaml-cpp/yaml.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/stroke.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {

Eigen::Vector2d strokePx(const StrokeValues& stroke, double focal_px) {
  return Eigen::Vector2d(focal_px * std::tan(stroke.stroke_x_deg * stage_numerics::kDegToRad),
                         focal_px * std::tan(stroke.stroke_y_deg * stage_numerics::kDegToRad));
}

Eigen::Vector2d strokePx(const StabiliserModel& model, double focal_px) {
  const StrokeValues* stroke = model.find<StrokeValues>();
  return strokePx(stroke ? *stroke : StrokeValues(), focal_px);
}

namespace {

// The command the stroke lets through: per axis for a box, radially for an ellipse; an end stop
// (the nearest point of the stroke) or, soft, stroke * tanh(command / stroke).
Eigen::Vector2d limitToStroke(const Eigen::Vector2d& command, const Eigen::Vector2d& limit_px,
                              bool circular, bool soft) {
  if (soft && !circular) {
    return Eigen::Vector2d(limit_px.x() * std::tanh(command.x() / limit_px.x()),
                           limit_px.y() * std::tanh(command.y() / limit_px.y()));
  }
  if (soft) {
    const double r = std::hypot(command.x() / limit_px.x(), command.y() / limit_px.y());
    return r > 1e-12 ? Eigen::Vector2d(command * (std::tanh(r) / r)) : command;
  }
  if (!circular) {
    return Eigen::Vector2d(std::clamp(command.x(), -limit_px.x(), limit_px.x()),
                           std::clamp(command.y(), -limit_px.y(), limit_px.y()));
  }
  const double r = std::hypot(command.x() / limit_px.x(), command.y() / limit_px.y());
  return r > 1.0 ? Eigen::Vector2d(command / r) : command;
}

// Limits the raw command; with anti-windup holds the angle where its command meets the stroke.
class StrokeRunner final : public StabiliserStageRunner {
 public:
  StrokeRunner(const StrokeValues& p, const StabiliserModel& model, const StabiliserRunContext& context)
      : stroke_px_(strokePx(p, context.focal_px)),
        circular_(p.circular_stroke),
        soft_(p.soft_stroke),
        focal_px_(context.focal_px) {
    // Anti-windup needs the angle that gives a limited command, through the centring's gain: with
    // a gain that is not invertible (no lens motion, gain 0) there is none, and nothing winds up
    // that the lens would show; nor without a centring stage (no angle to hold).
    const CentringValues* centring = model.find<CentringValues>();
    if (p.anti_windup && centring) {
      const Eigen::Matrix2d& gain = centring->gain;
      const double scale = gain.cwiseAbs().maxCoeff();
      if (scale > 0.0 && std::abs(gain.determinant()) > 1e-6 * scale * scale) {
        anti_windup_ = true;
        inverse_gain_ = gain.inverse();
      }
    }
  }
  void reset(StabiliserSignal& signal) override { signal.excursion_sq = 0.0; }
  void advance(StabiliserSignal& signal) override {
    Eigen::Vector2d& raw_command = signal.raw_command_px;
    signal.command_px = limitToStroke(raw_command, stroke_px_, circular_, soft_);
    if (anti_windup_ && signal.command_px != raw_command) {
      // Held at the end stop: the angle is the one whose command is the limited one.
      const Eigen::Vector2d tangent = inverse_gain_ * (signal.command_px / focal_px_);
      signal.angle_rad = Eigen::Vector2d(std::atan(tangent.x()), std::atan(tangent.y()));
      raw_command = signal.command_px;
    }
    signal.excursion_sq = (raw_command.cwiseQuotient(stroke_px_)).squaredNorm();
    signal.lens_px = signal.command_px;  // until an actuator after it moves the lens
  }

 private:
  Eigen::Vector2d stroke_px_;
  bool circular_, soft_;
  double focal_px_;
  bool anti_windup_ = false;
  Eigen::Matrix2d inverse_gain_ = Eigen::Matrix2d::Zero();
};

}  // namespace

const StabiliserStage& strokeStage() {
  static const StabiliserStage stage{
      "stroke",
      "the command is limited to the stroke (a box of two limits as angles, or the ellipse inside "
      "it), at an end stop or softly (tanh); at an end stop the integrator winds up or is held "
      "(anti-windup)",
      true,
      {{"stroke_x_deg", "stroke x", "deg", true, 0.02, 20.0, 1e-3,
        [](const StageValues& v) { return valuesAs<StrokeValues>(v).stroke_x_deg; },
        [](StageValues& v, double value) { valuesAs<StrokeValues>(v).stroke_x_deg = value; }, nullptr},
       {"stroke_y_deg", "stroke y", "deg", true, 0.02, 20.0, 1e-3,
        [](const StageValues& v) { return valuesAs<StrokeValues>(v).stroke_y_deg; },
        [](StageValues& v, double value) { valuesAs<StrokeValues>(v).stroke_y_deg = value; }, nullptr}},
      {"stroke_x_deg", "stroke_y_deg", "circular_stroke", "soft_stroke", "anti_windup"},
      stage_numerics::make<StrokeValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const StrokeValues& p = valuesAs<StrokeValues>(own);
        out << YAML::Key << "stroke_x_deg" << YAML::Value << p.stroke_x_deg;
        out << YAML::Key << "stroke_y_deg" << YAML::Value << p.stroke_y_deg;
        out << YAML::Key << "circular_stroke" << YAML::Value << p.circular_stroke;
        // Optional (written only when used): files without them, every model before these
        // mechanisms, load as a winding-up integrator with an end stop.
        if (p.soft_stroke) out << YAML::Key << "soft_stroke" << YAML::Value << p.soft_stroke;
        if (p.anti_windup) out << YAML::Key << "anti_windup" << YAML::Value << p.anti_windup;
      },
      [](const YAML::Node& s, StageValues& own) {
        StrokeValues* p = &valuesAs<StrokeValues>(own);
        using stabiliser_file_fields::optional;
        using stabiliser_file_fields::required;
        p->stroke_x_deg = required<double>(s, "stroke_x_deg");
        p->stroke_y_deg = required<double>(s, "stroke_y_deg");
        p->circular_stroke = required<bool>(s, "circular_stroke");
        p->soft_stroke = optional<bool>(s, "soft_stroke", false);
        p->anti_windup = optional<bool>(s, "anti_windup", false);
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const StrokeValues& p = valuesAs<StrokeValues>(own);
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
      stage_numerics::runner<StrokeRunner, StrokeValues>,
      [](const StageValues& own) {
        const StrokeValues& p = valuesAs<StrokeValues>(own);
        return std::string(p.soft_stroke ? "stroke:soft" : p.anti_windup ? "stroke:anti_windup" : "stroke");
      },
      [](StageValues& own, const char* variant) {
        StrokeValues* p = &valuesAs<StrokeValues>(own);
        const std::string v = variant ? variant : "";
        if (v != "" && v != "soft" && v != "anti_windup")
          throw std::invalid_argument("stroke: no variant '" + v + "' (soft, anti_windup)");
        p->soft_stroke = v == "soft";
        p->anti_windup = v == "anti_windup";
      }};
  return stage;
}

}  // namespace deep_ois
