// The centring stage: the commanded shift f * gain * tan(theta) for the pan/tilt angle theta, which
// leaks back to the centre with the high-pass corner (the stabiliser's re-centring).
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <limits>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Integrates the pan/tilt rate into the angle, leaking back with the corner (or as the stages
// before it decided), and commands f * gain * tan(angle).
class CentringRunner final : public StabiliserStageRunner {
 public:
  CentringRunner(const CentringValues& p, const StabiliserModel&, const StabiliserRunContext& context)
      : corner_rad_s_(2.0 * stage_numerics::kPi * p.highpass_corner_hz),
        step_s_(context.step_s),
        decay_(stage_numerics::leakDecay(corner_rad_s_, step_s_)),
        weight_(stage_numerics::leakWeight(corner_rad_s_, step_s_)),
        gain_(p.gain),
        focal_px_(context.focal_px) {}
  void reset(StabiliserSignal& signal) override { signal.angle_rad.setZero(); }
  void advance(StabiliserSignal& signal) override {
    using stage_numerics::leakDecay;
    using stage_numerics::leakWeight;
    const Eigen::Vector2d pan_tilt = signal.rate_rad_s.head<2>();
    Eigen::Vector2d& theta = signal.angle_rad;
    if (signal.released) {
      theta = signal.release_decay * theta + signal.release_weight * pan_tilt;
    } else if (signal.corner_scale != 1.0) {
      const double corner = corner_rad_s_ * signal.corner_scale;
      theta = leakDecay(corner, step_s_) * theta + leakWeight(corner, step_s_) * pan_tilt;
    } else {
      theta = decay_ * theta + weight_ * pan_tilt;
    }
    signal.raw_command_px =
        focal_px_ * (gain_ * Eigen::Vector2d(std::tan(theta.x()), std::tan(theta.y())));
    // Until a stroke or an actuator after it acts.
    signal.command_px = signal.lens_px = signal.raw_command_px;
  }

 private:
  double corner_rad_s_, step_s_, decay_, weight_;
  Eigen::Matrix2d gain_;
  double focal_px_;
};

constexpr double kInf = std::numeric_limits<double>::infinity();

// The gain's entries, unbounded (its sign and axes are the camera's), linear in the fit.
template <int kRow, int kCol>
FittedStabiliserParameter gainEntry(const char* name) {
  return {name,
          "gain",
          "",
          false,
          -kInf,
          kInf,
          1e-4,
          [](const StageValues& v) { return valuesAs<CentringValues>(v).gain(kRow, kCol); },
          [](StageValues& v, double value) { valuesAs<CentringValues>(v).gain(kRow, kCol) = value; },
          nullptr};
}

}  // namespace

const StabiliserStage& centringStage() {
  static const StabiliserStage stage{
      "centring",
      "the commanded shift f * gain * tan(angle) of the integrated pan/tilt angle, which leaks back "
      "to the centre with the high-pass corner",
      true,
      {gainEntry<0, 0>("gain_xx"), gainEntry<0, 1>("gain_xy"), gainEntry<1, 0>("gain_yx"),
       gainEntry<1, 1>("gain_yy"),
       {"highpass_corner_hz", "centring corner", "Hz", true, 1e-3, 50.0, 1e-3,
        [](const StageValues& v) { return valuesAs<CentringValues>(v).highpass_corner_hz; },
        [](StageValues& v, double value) { valuesAs<CentringValues>(v).highpass_corner_hz = value; },
        nullptr}},
      {"gain", "highpass_corner_hz"},
      stage_numerics::make<CentringValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const CentringValues& p = valuesAs<CentringValues>(own);
        out << YAML::Key << "gain" << YAML::Value << YAML::Flow
            << stabiliser_file_fields::rowMajor(p.gain);
        out << YAML::Key << "highpass_corner_hz" << YAML::Value << p.highpass_corner_hz;
      },
      [](const YAML::Node& s, StageValues& own) {
        CentringValues* p = &valuesAs<CentringValues>(own);
        using stabiliser_file_fields::required;
        const auto gain = required<std::vector<double>>(s, "gain");
        if (gain.size() != 4) throw StabiliserModelFileError("field 'gain' must have 4 values");
        p->gain << gain[0], gain[1], gain[2], gain[3];
        p->highpass_corner_hz = required<double>(s, "highpass_corner_hz");
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const CentringValues& p = valuesAs<CentringValues>(own);
        std::ostringstream why;
        if (!p.gain.allFinite()) {
          why << "gain: must be finite";
        } else if (!std::isfinite(p.highpass_corner_hz) || p.highpass_corner_hz < 0.0) {
          why << "highpass_corner_hz: must be >= 0 (got " << p.highpass_corner_hz << ")";
        }
        return why.str();
      },
      stage_numerics::runner<CentringRunner, CentringValues>,
      [](const StageValues&) { return std::string("centring"); }, nullptr};
  return stage;
}

}  // namespace deep_ois
