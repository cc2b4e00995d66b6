// The pan detection stage: while the low-passed |pan/tilt rate| exceeds the threshold the
// stabiliser re-centres with the release corner (it lets a deliberate pan through); below 0.7 x the
// threshold it holds again. The threshold is chosen from a grid by the fit (its hysteresis makes
// the cost step-like in it); the release corner is fitted when detection is on.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Decides, before the centring runs, whether this step re-centres with the release corner.
class PanDetectionRunner final : public StabiliserStageRunner {
 public:
  PanDetectionRunner(const StabiliserParameters& p, const StabiliserRunContext& context)
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
        [](const StabiliserParameters& p) { return p.pan_release_corner_hz; },
        [](StabiliserParameters* p, double value) { p->pan_release_corner_hz = value; },
        [](const StabiliserParameters& p) { return p.pan_detection_rate_rad_s > 0.0; }}},
      {"pan_detection_rate_rad_s", "pan_detection_time_constant_s", "pan_release_corner_hz"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        out << YAML::Key << "pan_detection_rate_rad_s" << YAML::Value << p.pan_detection_rate_rad_s;
        out << YAML::Key << "pan_detection_time_constant_s" << YAML::Value
            << p.pan_detection_time_constant_s;
        out << YAML::Key << "pan_release_corner_hz" << YAML::Value << p.pan_release_corner_hz;
      },
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::required;
        p->pan_detection_rate_rad_s = required<double>(s, "pan_detection_rate_rad_s");
        p->pan_detection_time_constant_s = required<double>(s, "pan_detection_time_constant_s");
        p->pan_release_corner_hz = required<double>(s, "pan_release_corner_hz");
      },
      [](const StabiliserParameters& p) {
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
      nullptr,
      [](const StabiliserParameters& p, const StabiliserRunContext& context) {
        return p.pan_detection_rate_rad_s > 0.0 ? stage_numerics::runner<PanDetectionRunner>(p, context)
                                                : nullptr;
      },
      [](const StabiliserParameters& p) {
        return std::string(p.pan_detection_rate_rad_s > 0.0 ? "pan_detection" : "");
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
