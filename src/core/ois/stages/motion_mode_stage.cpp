// The motion-mode stage of a sampled controller: pan detection on the sustained pan/tilt rate (the
// norm of the rate vector's low-pass, in which the shake averages out; on above the threshold, off
// below 0.7 x it) that either releases (the intended-motion corner times release_factor while
// panning) or holds (the gain ramps to 0 and back), and a gain schedule that lowers the gain with
// the low-passed motion (from 1 at schedule_start to 1 - schedule_depth a span later).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

stabiliser_file_fields::ValueFields fields(MotionModeValues& v) {
  return {{{"threshold_rad_s", &v.threshold_rad_s},
           {"time_constant_s", &v.time_constant_s},
           {"release_factor", &v.release_factor},
           {"hold_time_constant_s", &v.hold_time_constant_s},
           {"schedule_depth", &v.schedule_depth},
           {"schedule_start_rad_s", &v.schedule_start_rad_s},
           {"schedule_span_rad_s", &v.schedule_span_rad_s},
           {"schedule_time_constant_s", &v.schedule_time_constant_s}},
          {{"action", &v.action}, {"detector", &v.detector}},
          {}};
}

bool acts(const StageValues& own) {
  const MotionModeValues& v = valuesAs<MotionModeValues>(own);
  return v.action != "none" || v.schedule_depth > 0.0;
}

class MotionModeRunner final : public StabiliserStageRunner {
 public:
  MotionModeRunner(const MotionModeValues& p, const StabiliserModel& model,
                   const StabiliserRunContext& context)
      : v_(p),
        detects_(v_.action != "none"),
        on_norm_(v_.detector == "norm"),
        releases_(v_.action == "release"),
        T_(stage_numerics::controlPeriod(model, context)) {}
  void reset(StabiliserSignal& signal) override {
    sustained_rate_.setZero();
    sustained_norm_ = 0.0;
    panning_ = false;
    hold_gain_ = 1.0;
    schedule_level_ = 0.0;
    signal.corner_scale = signal.gain_scale = 1.0;
  }
  void advance(StabiliserSignal& signal) override {
    if (!signal.control_tick) return;
    const Eigen::Vector2d& rate = signal.sampled_rate_rad_s;
    double release = 1.0;
    if (detects_) {
      const double smoothing = -std::expm1(-T_ / v_.time_constant_s);
      double level;
      if (on_norm_) {
        sustained_norm_ += smoothing * (signal.newest_rate_rad_s.norm() - sustained_norm_);
        level = sustained_norm_;
      } else {
        sustained_rate_ += smoothing * (rate - sustained_rate_);
        level = sustained_rate_.norm();
      }
      if (!panning_ && level > v_.threshold_rad_s) panning_ = true;
      if (panning_ && level < 0.7 * v_.threshold_rad_s) panning_ = false;
      if (releases_ && panning_) release = v_.release_factor;
      if (!releases_)
        hold_gain_ += -std::expm1(-T_ / v_.hold_time_constant_s) * ((panning_ ? 0.0 : 1.0) - hold_gain_);
    }
    double schedule = 1.0;
    if (v_.schedule_depth > 0.0) {
      schedule_level_ += -std::expm1(-T_ / v_.schedule_time_constant_s) * (rate.norm() - schedule_level_);
      const double x =
          std::clamp((schedule_level_ - v_.schedule_start_rad_s) / v_.schedule_span_rad_s, 0.0, 1.0);
      schedule = 1.0 - v_.schedule_depth * x;
    }
    signal.corner_scale = release;
    signal.gain_scale = hold_gain_ * schedule;
  }

 private:
  MotionModeValues v_;
  bool detects_, on_norm_, releases_;  // a pan is detected (on the norm); it releases (else holds)
  double T_;
  Eigen::Vector2d sustained_rate_ = Eigen::Vector2d::Zero();
  double sustained_norm_ = 0.0;
  bool panning_ = false;
  double hold_gain_ = 1.0, schedule_level_ = 0.0;
};

}  // namespace

const StabiliserStage& motionModeStage() {
  static const StabiliserStage stage{
      "motion_mode",
      "pan detection on the sustained rate that releases (corner x release_factor) or holds (gain "
      "to 0), and a gain schedule that lowers the gain with the motion",
      false,
      {},
      {"motion_mode"},
      stage_numerics::make<MotionModeValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        MotionModeValues v = valuesAs<MotionModeValues>(own);
        stabiliser_file_fields::writeValueMap(out, "motion_mode", fields(v));
      },
      [](const YAML::Node& s, StageValues& own) {
        return stabiliser_file_fields::readValueMap(s, "motion_mode", fields(valuesAs<MotionModeValues>(own)));
      },
      [](const StageValues& own, const StabiliserModel&) {
        std::ostringstream why;
        const MotionModeValues& v = valuesAs<MotionModeValues>(own);
        if (v.action != "none" && v.action != "release" && v.action != "hold")
          why << "motion_mode.action: must be none, release or hold (got '" << v.action << "')";
        else if (v.detector != "vector" && v.detector != "norm")
          why << "motion_mode.detector: must be vector or norm (got '" << v.detector << "')";
        else if (!(v.threshold_rad_s > 0.0 && v.time_constant_s > 0.0 && v.release_factor >= 1.0 &&
                   v.hold_time_constant_s > 0.0))
          why << "motion_mode: threshold and time constants must be positive, release_factor >= 1";
        else if (!(v.schedule_depth >= 0.0 && v.schedule_depth < 1.0 && v.schedule_span_rad_s > 0.0 &&
                   v.schedule_time_constant_s > 0.0))
          why << "motion_mode: schedule_depth must be in [0, 1), its span and time constant positive";
        return why.str();
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        return acts(own) ? stage_numerics::runner<MotionModeRunner, MotionModeValues>(own, model, context)
                         : nullptr;
      },
      [](const StageValues& own) { return std::string(acts(own) ? "motion_mode" : ""); },
      nullptr};
  return stage;
}

}  // namespace deep_ois
