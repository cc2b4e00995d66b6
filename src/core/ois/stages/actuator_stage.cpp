// The actuator stage: the voice-coil position loop that moves the lens to the command, a second
// order system (natural frequency, damping) acting on commands as old as the Hall sensor's lag.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"

namespace deep_ois {

const StabiliserStage& actuatorStage() {
  static const StabiliserStage stage{
      "actuator",
      "the lens follows the command through a second-order position loop (natural frequency, "
      "damping) acting on commands as old as the sensor lag",
      true,
      {{"actuator_natural_hz", "actuator natural frequency", "Hz", true, 2.0, 500.0, 1e-3, "",
        [](const StabiliserParameters& p) { return p.actuator_natural_hz; },
        [](StabiliserParameters* p, double value) { p->actuator_natural_hz = value; }, nullptr},
       {"actuator_damping", "actuator damping", "", true, 0.05, 5.0, 1e-3, "",
        [](const StabiliserParameters& p) { return p.actuator_damping; },
        [](StabiliserParameters* p, double value) { p->actuator_damping = value; }, nullptr},
       // Fitted in milliseconds (a step of 0.01 ms), linear: a lag of 0 is a module's own.
       {"sensor_lag_s", "sensor lag", "ms", false, 0.0, 50.0, 1e-2, "",
        [](const StabiliserParameters& p) { return 1000.0 * p.sensor_lag_s; },
        [](StabiliserParameters* p, double value) { p->sensor_lag_s = value / 1000.0; }, nullptr}},
      {"actuator_natural_hz", "actuator_damping", "sensor_lag_s"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        out << YAML::Key << "actuator_natural_hz" << YAML::Value << p.actuator_natural_hz;
        out << YAML::Key << "actuator_damping" << YAML::Value << p.actuator_damping;
        out << YAML::Key << "sensor_lag_s" << YAML::Value << p.sensor_lag_s;
      },
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::required;
        p->actuator_natural_hz = required<double>(s, "actuator_natural_hz");
        p->actuator_damping = required<double>(s, "actuator_damping");
        p->sensor_lag_s = required<double>(s, "sensor_lag_s");
      },
      [](const StabiliserParameters& p) {
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
      nullptr};
  return stage;
}

}  // namespace deep_ois
