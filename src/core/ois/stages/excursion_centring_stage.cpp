// The excursion re-centring stage: the centring corner grows with the command's excursion against
// the stroke, corner * (1 + k e^2) (a stabiliser that pulls back harder near its end stop).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Excursions beyond this many strokes are not weighted further (keeps the corner bounded when a
// badly fitted stroke is small).
constexpr double kMaxExcursion = 3.0;

using Values = ExcursionCentringValues;
double k(const StageValues& own) { return valuesAs<Values>(own).excursion_centring; }

// Scales the centring's corner by the last step's excursion (unless a pan releases it).
class ExcursionCentringRunner final : public StabiliserStageRunner {
 public:
  ExcursionCentringRunner(const Values& p, const StabiliserModel&, const StabiliserRunContext&)
      : k_(p.excursion_centring) {}
  void reset(StabiliserSignal& signal) override { signal.corner_scale = 1.0; }
  void advance(StabiliserSignal& signal) override {
    signal.corner_scale =
        signal.released ? 1.0 : 1.0 + k_ * std::min(signal.excursion_sq, kMaxExcursion * kMaxExcursion);
  }

 private:
  double k_;
};

}  // namespace

const StabiliserStage& excursionCentringStage() {
  static const StabiliserStage stage{
      "excursion_centring",
      "the centring corner grows with the command's excursion e against the stroke: corner * (1 + "
      "k e^2); k = 0 is a fixed corner",
      true,
      {{"excursion_centring", "excursion-dependent re-centring", "", true, 1e-3, 100.0, 1e-3,
        [](const StageValues& v) { return k(v); },
        [](StageValues& v, double value) { valuesAs<Values>(v).excursion_centring = value; },
        [](const StageValues& v) { return k(v) > 0.0; }}},
      {"excursion_centring"},
      stage_numerics::make<Values>,
      [](YAML::Emitter& out, const StageValues& own) {
        // Optional: files without it load with a fixed corner.
        if (k(own) != 0.0) out << YAML::Key << "excursion_centring" << YAML::Value << k(own);
      },
      [](const YAML::Node& s, StageValues& own) {
        valuesAs<Values>(own).excursion_centring =
            stabiliser_file_fields::optional<double>(s, "excursion_centring", 0.0);
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        std::ostringstream why;
        if (!std::isfinite(k(own)) || k(own) < 0.0)
          why << "excursion_centring: must be >= 0, 0 = off (got " << k(own) << ")";
        return why.str();
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        return k(own) > 0.0 ? stage_numerics::runner<ExcursionCentringRunner, Values>(own, model, context)
                            : nullptr;
      },
      [](const StageValues& own) { return std::string(k(own) > 0.0 ? "excursion_centring" : ""); },
      // Starts from k = 1 (its fit's bound 0.001 is named when it wants none).
      [](StageValues& own, const char* variant) {
        valuesAs<Values>(own).excursion_centring = variant ? 1.0 : 0.0;
      }};
  return stage;
}

}  // namespace deep_ois
