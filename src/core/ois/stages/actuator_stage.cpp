// The actuator stage: the voice-coil position loop that moves the lens to the command, a second
// order system (natural frequency, damping) acting on commands as old as the Hall sensor's lag.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <deque>
#include <sstream>

#include "deep_ois/core/ois/lens_actuator.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/stroke.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Moves the lens (per axis, core/ois/lens_actuator.h) to the command of sensor_lag_s ago. The
// lens itself stops at the stroke too (the command never asks for more).
class ActuatorRunner final : public StabiliserStageRunner {
 public:
  ActuatorRunner(const ActuatorValues& p, const StabiliserModel& model, const StabiliserRunContext& context)
      : natural_hz_(p.actuator_natural_hz),
        damping_(p.actuator_damping),
        step_s_(context.step_s),
        stroke_px_(strokePx(model, context.focal_px)),  // the lens' end stop
        x_(natural_hz_, damping_, step_s_, stroke_px_.x()),
        y_(natural_hz_, damping_, step_s_, stroke_px_.y()) {
    // A fractional lag: the acted command is interpolated between the two stored around it (so
    // the fit sees a smooth cost in the lag).
    const double lag_steps = p.sensor_lag_s / step_s_;
    lag_steps_ = static_cast<std::size_t>(std::floor(lag_steps));
    lag_fraction_ = lag_steps - static_cast<double>(lag_steps_);
  }
  void reset(StabiliserSignal&) override {
    pending_commands_.assign(lag_steps_ + 1, Eigen::Vector2d::Zero());  // commands of the last steps
    x_ = LensActuator(natural_hz_, damping_, step_s_, stroke_px_.x());
    y_ = LensActuator(natural_hz_, damping_, step_s_, stroke_px_.y());
  }
  void advance(StabiliserSignal& signal) override {
    // Holds lag_steps_ + 2 commands after the push: front = lag_steps_ + 1 steps old.
    pending_commands_.push_back(signal.command_px);
    const Eigen::Vector2d acted =
        lag_fraction_ * pending_commands_[0] + (1.0 - lag_fraction_) * pending_commands_[1];
    pending_commands_.pop_front();
    signal.actuator_px = Eigen::Vector2d(x_.advance(acted.x()), y_.advance(acted.y()));
    signal.lens_px = signal.actuator_px;
  }

 private:
  double natural_hz_, damping_, step_s_;
  Eigen::Vector2d stroke_px_;
  std::size_t lag_steps_ = 0;  // whole steps of sensor lag
  double lag_fraction_ = 0.0;  // and the fraction of one more
  std::deque<Eigen::Vector2d> pending_commands_;
  LensActuator x_, y_;
};

}  // namespace

const StabiliserStage& actuatorStage() {
  static const StabiliserStage stage{
      "actuator",
      "the lens follows the command through a second-order position loop (natural frequency, "
      "damping) acting on commands as old as the sensor lag",
      true,
      {{"actuator_natural_hz", "actuator natural frequency", "Hz", true, 2.0, 500.0, 1e-3,
        [](const StageValues& v) { return valuesAs<ActuatorValues>(v).actuator_natural_hz; },
        [](StageValues& v, double value) { valuesAs<ActuatorValues>(v).actuator_natural_hz = value; }, nullptr},
       {"actuator_damping", "actuator damping", "", true, 0.05, 5.0, 1e-3,
        [](const StageValues& v) { return valuesAs<ActuatorValues>(v).actuator_damping; },
        [](StageValues& v, double value) { valuesAs<ActuatorValues>(v).actuator_damping = value; }, nullptr},
       // Fitted in milliseconds (a step of 0.01 ms), linear: a lag of 0 is a module's own.
       {"sensor_lag_s", "sensor lag", "ms", false, 0.0, 50.0, 1e-2,
        [](const StageValues& v) { return 1000.0 * valuesAs<ActuatorValues>(v).sensor_lag_s; },
        [](StageValues& v, double value) { valuesAs<ActuatorValues>(v).sensor_lag_s = value / 1000.0; },
        nullptr}},
      {"actuator_natural_hz", "actuator_damping", "sensor_lag_s"},
      stage_numerics::make<ActuatorValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const ActuatorValues& p = valuesAs<ActuatorValues>(own);
        out << YAML::Key << "actuator_natural_hz" << YAML::Value << p.actuator_natural_hz;
        out << YAML::Key << "actuator_damping" << YAML::Value << p.actuator_damping;
        out << YAML::Key << "sensor_lag_s" << YAML::Value << p.sensor_lag_s;
      },
      [](const YAML::Node& s, StageValues& own) {
        ActuatorValues* p = &valuesAs<ActuatorValues>(own);
        using stabiliser_file_fields::required;
        p->actuator_natural_hz = required<double>(s, "actuator_natural_hz");
        p->actuator_damping = required<double>(s, "actuator_damping");
        p->sensor_lag_s = required<double>(s, "sensor_lag_s");
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const ActuatorValues& p = valuesAs<ActuatorValues>(own);
        auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
        std::ostringstream why;
        if (!positive(p.actuator_natural_hz)) {
          why << "actuator_natural_hz: must be positive (got " << p.actuator_natural_hz << ")";
        } else if (!positive(p.actuator_damping)) {
          why << "actuator_damping: must be positive (got " << p.actuator_damping << ")";
        } else if (!std::isfinite(p.sensor_lag_s) || p.sensor_lag_s < 0.0 || p.sensor_lag_s > 0.1) {
          why << "sensor_lag_s: must be in [0, 0.1] s (got " << p.sensor_lag_s << ")";
        }
        return why.str();
      },
      stage_numerics::runner<ActuatorRunner, ActuatorValues>,
      [](const StageValues&) { return std::string("actuator"); }, nullptr};
  return stage;
}

}  // namespace deep_ois
