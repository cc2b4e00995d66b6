// The gyro-loop stage: the stabiliser's own gyro, turned against the camera (roll about the optical
// axis, then small tilt and pan errors of the die: it sees part of the camera's roll as pan and
// tilt), and a controller that samples it at its own rate (the newest sample, the mean over its
// period, or for a continuous controller the rate at the step's middle) and holds its command in
// between. The first stage of a sampled controller
// (motion_mode, intended_motion, travel and hall_actuator update only when it ticks).
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

stabiliser_file_fields::ValueFields fields(GyroLoopValues& v) {
  return {{{"roll_deg", &v.roll_deg},
           {"tilt_deg", &v.tilt_deg},
           {"pan_deg", &v.pan_deg},
           {"rate_hz", &v.rate_hz}},
          {{"sampling", &v.sampling}},
          {}};
}

class GyroLoopRunner final : public StabiliserStageRunner {
 public:
  GyroLoopRunner(const GyroLoopValues& p, const StabiliserModel& model,
                 const StabiliserRunContext& context)
      : averaged_(p.sampling == "averaged"),
        middle_(p.sampling == "middle"),
        tick_(stage_numerics::controlTick(model, context)) {
    if (middle_ && tick_ != 1)
      throw std::invalid_argument(
          "gyro_loop: sampling 'middle' needs rate_hz equal to the step's rate");
    using stage_numerics::kDegToRad;
    const GyroLoopValues& v = p;
    to_gyro_ = (Eigen::AngleAxisd(v.pan_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(v.tilt_deg * kDegToRad, Eigen::Vector3d::UnitX()) *
                Eigen::AngleAxisd(v.roll_deg * kDegToRad, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix()
                   .transpose();
  }
  void reset(StabiliserSignal&) override { sum_rate_.setZero(); }
  void advance(StabiliserSignal& signal) override {
    // The gyro at the end of the step, in its own axes, with its noise (a simulator's).
    const Eigen::Vector3d w = to_gyro_ * signal.end_rate_rad_s;
    const Eigen::Vector2d measured = w.head<2>() + signal.gyro_noise_rad_s;
    sum_rate_ += measured;
    signal.control_tick = signal.step_index % tick_ == 0;
    if (!signal.control_tick) return;
    signal.newest_rate_rad_s = measured;
    if (middle_) {
      signal.sampled_rate_rad_s =
          (to_gyro_ * signal.rate_rad_s).head<2>() + signal.gyro_noise_mid_rad_s;
    } else {
      signal.sampled_rate_rad_s =
          averaged_ ? Eigen::Vector2d(sum_rate_ / static_cast<double>(tick_)) : measured;
    }
    sum_rate_.setZero();
  }

 private:
  Eigen::Matrix3d to_gyro_;
  bool averaged_, middle_;
  long long tick_;
  Eigen::Vector2d sum_rate_ = Eigen::Vector2d::Zero();
};

}  // namespace

const StabiliserStage& gyroLoopStage() {
  static const StabiliserStage stage{
      "gyro_loop",
      "the stabiliser's gyro turned against the camera (roll, tilt, pan, deg) and sampled by a "
      "controller at rate_hz (newest sample, averaged, or the step's middle), its command held in "
      "between",
      false,
      {},
      {"gyro_loop"},
      stage_numerics::make<GyroLoopValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        GyroLoopValues v = valuesAs<GyroLoopValues>(own);
        stabiliser_file_fields::writeValueMap(out, "gyro_loop", fields(v));
      },
      [](const YAML::Node& s, StageValues& own) {
        GyroLoopValues& v = valuesAs<GyroLoopValues>(own);
        // Files written before `sampling` said `averaged: true|false` (the newest sample when
        // false): read as the same sampling, so they predict as they did.
        const YAML::Node loop = s["gyro_loop"];
        if (loop && loop.IsMap() && loop["averaged"] && !loop["sampling"]) {
          YAML::Node converted = YAML::Clone(s);
          const bool averaged = stabiliser_file_fields::required<bool>(loop, "averaged");
          converted["gyro_loop"]["sampling"] = averaged ? "averaged" : "latest";
          return stabiliser_file_fields::readValueMap(converted, "gyro_loop", fields(v));
        }
        return stabiliser_file_fields::readValueMap(s, "gyro_loop", fields(v));
      },
      [](const StageValues& own, const StabiliserModel&) {
        std::ostringstream why;
        const GyroLoopValues& v = valuesAs<GyroLoopValues>(own);
        if (!(std::abs(v.roll_deg) <= 45.0 && std::abs(v.tilt_deg) <= 45.0 && std::abs(v.pan_deg) <= 45.0))
          why << "gyro_loop: roll_deg, tilt_deg and pan_deg must be within +-45";
        else if (v.sampling != "latest" && v.sampling != "averaged" && v.sampling != "middle")
          why << "gyro_loop.sampling: must be latest, averaged or middle (got '" << v.sampling
              << "')";
        else if (!(v.rate_hz > 0.0 && v.rate_hz < 1e6))
          why << "gyro_loop.rate_hz: must be positive (got " << v.rate_hz << ")";
        return why.str();
      },
      stage_numerics::runner<GyroLoopRunner, GyroLoopValues>,
      [](const StageValues&) { return std::string("gyro_loop"); },
      nullptr};
  return stage;
}

}  // namespace deep_ois
