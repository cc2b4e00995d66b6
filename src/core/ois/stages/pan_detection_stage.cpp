// The pan detection stage: while the low-passed |pan/tilt rate| exceeds the threshold the
// stabiliser re-centres with the release corner (it lets a deliberate pan through); below 0.7 x the
// threshold it holds again. The threshold is chosen from a grid by the fit (its hysteresis makes
// the cost step-like in it); the release corner is fitted when detection is on.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

using Values = PanDetectionValues;
bool detects(const StageValues& own) { return valuesAs<Values>(own).pan_detection_rate_rad_s > 0.0; }

// Decides, before the centring runs, whether this step re-centres with the release corner.
class PanDetectionRunner final : public StabiliserStageRunner {
 public:
  PanDetectionRunner(const Values& p, const StabiliserModel&, const StabiliserRunContext& context)
      : threshold_rad_s_(p.pan_detection_rate_rad_s),
        smoothing_(-std::expm1(-context.step_s / p.pan_detection_time_constant_s)),
        release_decay_(stage_numerics::leakDecay(2.0 * stage_numerics::kPi * p.pan_release_corner_hz,
                                                 context.step_s)),
        release_weight_(stage_numerics::leakWeight(
            2.0 * stage_numerics::kPi * p.pan_release_corner_hz, context.step_s)) {}
  void reset(StabiliserSignal& signal) override {
    smoothed_rate_ = 0.0;
    panning_ = false;
    signal.released = false;
  }
  void advance(StabiliserSignal& signal) override {
    smoothed_rate_ += smoothing_ * (signal.rate_rad_s.head<2>().norm() - smoothed_rate_);
    if (!panning_ && smoothed_rate_ > threshold_rad_s_) panning_ = true;
    if (panning_ && smoothed_rate_ < 0.7 * threshold_rad_s_) panning_ = false;
    signal.released = panning_;
    signal.release_decay = release_decay_;
    signal.release_weight = release_weight_;
  }

 private:
  double threshold_rad_s_, smoothing_, release_decay_, release_weight_;
  double smoothed_rate_ = 0.0;  // low-passed |pan/tilt rate|, rad/s
  bool panning_ = false;
};

}  // namespace

const StabiliserStage& panDetectionStage() {
  static const StabiliserStage stage{
      "pan_detection",
      "while the low-passed pan/tilt rate exceeds the threshold (0 = off) the angle re-centres "
      "with the release corner; below 0.7 x the threshold it holds again",
      true,
      {{"pan_release_corner_hz", "pan release corner", "Hz", true, 0.05, 100.0, 1e-3,
        [](const StageValues& v) { return valuesAs<Values>(v).pan_release_corner_hz; },
        [](StageValues& v, double value) { valuesAs<Values>(v).pan_release_corner_hz = value; },
        detects}},
      {"pan_detection_rate_rad_s", "pan_detection_time_constant_s", "pan_release_corner_hz"},
      stage_numerics::make<Values>,
      [](YAML::Emitter& out, const StageValues& own) {
        const Values& p = valuesAs<Values>(own);
        out << YAML::Key << "pan_detection_rate_rad_s" << YAML::Value << p.pan_detection_rate_rad_s;
        out << YAML::Key << "pan_detection_time_constant_s" << YAML::Value
            << p.pan_detection_time_constant_s;
        out << YAML::Key << "pan_release_corner_hz" << YAML::Value << p.pan_release_corner_hz;
      },
      [](const YAML::Node& s, StageValues& own) {
        Values* p = &valuesAs<Values>(own);
        using stabiliser_file_fields::required;
        p->pan_detection_rate_rad_s = required<double>(s, "pan_detection_rate_rad_s");
        p->pan_detection_time_constant_s = required<double>(s, "pan_detection_time_constant_s");
        p->pan_release_corner_hz = required<double>(s, "pan_release_corner_hz");
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const Values& p = valuesAs<Values>(own);
        auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
        std::ostringstream why;
        if (!std::isfinite(p.pan_detection_rate_rad_s) || p.pan_detection_rate_rad_s < 0.0) {
          why << "pan_detection_rate_rad_s: must be >= 0, 0 = off (got "
              << p.pan_detection_rate_rad_s << ")";
        } else if (!positive(p.pan_detection_time_constant_s)) {
          why << "pan_detection_time_constant_s: must be positive";
        } else if (!positive(p.pan_release_corner_hz)) {
          why << "pan_release_corner_hz: must be positive";
        }
        return why.str();
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        return detects(own) ? stage_numerics::runner<PanDetectionRunner, Values>(own, model, context)
                            : nullptr;
      },
      [](const StageValues& own) { return std::string(detects(own) ? "pan_detection" : ""); },
      nullptr};
  return stage;
}

}  // namespace deep_ois
