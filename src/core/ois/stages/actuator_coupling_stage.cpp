// The actuator coupling stage: the image shift is (a_x + c_xy a_y, a_y + c_yx a_x) for the
// actuator's output a (a lens whose axes drag each other, a magnet turned against its coil); with
// the gain it places the stroke's box in the actuator's axes instead of the image's.
#include <yaml-cpp/yaml.h>

#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

using Values = ActuatorCouplingValues;

bool coupled(const StageValues& own) { return !valuesAs<Values>(own).actuator_coupling.isZero(0.0); }

// The actuator's axes to the image's (after the stroke: a coupled lens can leave the box).
class ActuatorCouplingRunner final : public StabiliserStageRunner {
 public:
  ActuatorCouplingRunner(const Values& p, const StabiliserModel&, const StabiliserRunContext&)
      : coupling_(p.actuator_coupling) {}
  void reset(StabiliserSignal&) override {}
  void advance(StabiliserSignal& signal) override {
    Eigen::Vector2d& shift = signal.lens_px;
    shift += Eigen::Vector2d(coupling_.x() * shift.y(), coupling_.y() * shift.x());
  }

 private:
  Eigen::Vector2d coupling_;  // (c_xy, c_yx)
};

}  // namespace

const StabiliserStage& actuatorCouplingStage() {
  static const StabiliserStage stage{
      "actuator_coupling",
      "the image shift mixes the actuator's axes: (a_x + c_xy a_y, a_y + c_yx a_x); 0 = none",
      true,
      {{"actuator_coupling", "actuator coupling c_xy", "", false, -0.5, 0.5, 1e-4,
        [](const StageValues& v) { return valuesAs<Values>(v).actuator_coupling.x(); },
        [](StageValues& v, double value) { valuesAs<Values>(v).actuator_coupling.x() = value; }, coupled},
       {"actuator_coupling", "actuator coupling c_yx", "", false, -0.5, 0.5, 1e-4,
        [](const StageValues& v) { return valuesAs<Values>(v).actuator_coupling.y(); },
        [](StageValues& v, double value) { valuesAs<Values>(v).actuator_coupling.y() = value; }, coupled}},
      {"actuator_coupling"},
      stage_numerics::make<Values>,
      [](YAML::Emitter& out, const StageValues& own) {
        const Values& p = valuesAs<Values>(own);
        // Optional: files without it load uncoupled.
        if (coupled(own))
          out << YAML::Key << "actuator_coupling" << YAML::Value << YAML::Flow
              << std::vector<double>{p.actuator_coupling.x(), p.actuator_coupling.y()};
      },
      [](const YAML::Node& s, StageValues& own) {
        Values* p = &valuesAs<Values>(own);
        const auto coupling =
            stabiliser_file_fields::optional<std::vector<double>>(s, "actuator_coupling", {0.0, 0.0});
        if (coupling.size() != 2)
          throw StabiliserModelFileError("field 'actuator_coupling' must have 2 values (c_xy, c_yx)");
        p->actuator_coupling = Eigen::Vector2d(coupling[0], coupling[1]);
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const Values& p = valuesAs<Values>(own);
        std::ostringstream why;
        if (!p.actuator_coupling.allFinite() || p.actuator_coupling.cwiseAbs().maxCoeff() > 0.5)
          why << "actuator_coupling: must be within +-0.5 (got " << p.actuator_coupling.x() << ", "
              << p.actuator_coupling.y() << ")";
        return why.str();
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        return coupled(own) ? stage_numerics::runner<ActuatorCouplingRunner, Values>(own, model, context)
                            : nullptr;
      },
      [](const StageValues& own) { return std::string(coupled(own) ? "actuator_coupling" : ""); },
      // Starts at none: the chain itself, its gain then mapping into the stroke's axes.
      [](StageValues& own, const char*) { valuesAs<Values>(own).actuator_coupling.setZero(); }};
  return stage;
}

}  // namespace deep_ois
