// The Hall-actuator stage of a sampled controller: the command late by a transport delay (bus,
// driver IC; plus the one step the controller's update takes), then the lens under its Hall-sensor
// position loop per axis: first- or second-order dynamics discretised exactly for a command held
// over a step, or a spring-mass lens under a PI loop (a camera module's: zero steady-state error,
// a third-order closed loop that rings more), a slew limit, stiction (stick below the breakaway
// error, slide against half of it) and inelastic end stops at end_stop_margin x the stroke. The
// loop drives the Hall reading h(x) = x + c2 L (x/L)^2 + c3 L (x/L)^3 (L the axis' largest stroke)
// to the command, so the lens sits at h^-1 of it.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <sstream>

#include "deep_ois/core/common/matrix_exponential.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

using stage_numerics::kDegToRad;
using stage_numerics::kPi;

stabiliser_file_fields::ValueFields fields(HallActuatorValues& v) {
  return {{{"delay_s", &v.delay_s},
           {"bandwidth_hz", &v.bandwidth_hz},
           {"damping", &v.damping},
           {"rate_limit_deg_s", &v.rate_limit_deg_s},
           {"stiction_fraction", &v.stiction_fraction},
           {"pi_kp", &v.pi_kp},
           {"pi_ki", &v.pi_ki},
           {"end_stop_margin", &v.end_stop_margin},
           {"hall_c2", &v.hall_c2},
           {"hall_c3", &v.hall_c3}},
          {{"order", &v.order}},
          {}};
}

// One axis of the lens under its position loop, in Hall-reading units (pixels as the loop sees
// them).
class LensAxis {
 public:
  LensAxis(const HallActuatorValues& v, double step_s, double rate_limit_px_s, double breakaway_px,
           double low_stop, double high_stop)
      : first_order_(v.order == "first"),
        pi_(v.order == "pi"),
        kp_(v.pi_kp),
        ki_(v.pi_ki),
        h_(step_s),
        rate_limit_px_s_(rate_limit_px_s),
        breakaway_px_(breakaway_px),
        low_stop_(low_stop),
        high_stop_(high_stop) {
    const double wh = 2.0 * kPi * v.bandwidth_hz * step_s;
    natural_rad_s_ = 2.0 * kPi * v.bandwidth_hz;
    damping_ = v.damping;
    if (first_order_) {
      decay_ = std::exp(-wh);
    } else {
      // State (x, x' / wn): d/dt = wn [[0, 1], [-1, -2 zeta]] + wn (0, 1) u.
      Eigen::Matrix3d augmented;
      augmented << 0.0, wh, 0.0, -wh, -2.0 * v.damping * wh, wh, 0.0, 0.0, 0.0;
      const Eigen::Matrix3d e = matrixExponential(augmented);
      transition_ = e.topLeftCorner<2, 2>();
      input_ = e.topRightCorner<2, 1>();
    }
  }

  void reset() {
    position_ = velocity_scaled_ = integral_ = 0.0;
    stuck_ = breakaway_px_ > 0.0;  // at rest: held by its stiction until the loop pulls
  }

  double advance(double command) {
    const double error = command - position_;
    if (breakaway_px_ > 0.0) {
      if (stuck_ && std::abs(error) <= breakaway_px_) return position_;
      stuck_ = false;
    }
    // Sliding friction: the drive is short of the command by half the breakaway (never past it).
    const double drive = command - std::copysign(std::min(0.5 * breakaway_px_, std::abs(error)), error);
    const double before = position_;
    const double velocity_before = velocity_scaled_;
    if (pi_) {
      advancePi(drive);
    } else if (first_order_) {
      position_ = drive + (position_ - drive) * decay_;
    } else {
      const Eigen::Vector2d state = transition_ * Eigen::Vector2d(position_, velocity_scaled_) + input_ * drive;
      position_ = state.x();
      velocity_scaled_ = state.y();
    }
    if (rate_limit_px_s_ > 0.0) {
      const double step = rate_limit_px_s_ * h_;
      if (std::abs(position_ - before) > step) position_ = before + std::copysign(step, position_ - before);
      if (!first_order_ && std::abs(velocity_scaled_ * natural_rad_s_) > rate_limit_px_s_)
        velocity_scaled_ = std::copysign(rate_limit_px_s_ / natural_rad_s_, velocity_scaled_);
    }
    if (breakaway_px_ > 0.0) {
      const double left = std::abs(command - position_);
      // First order: it slows to a stop short of the command; second: it stops where its velocity
      // reverses, unless the loop's error there breaks it away again.
      const bool stopped = first_order_ ? left <= 0.55 * breakaway_px_
                                        : velocity_before * velocity_scaled_ < 0.0 && left <= breakaway_px_;
      if (stopped) {
        stuck_ = true;
        velocity_scaled_ = 0.0;
      }
    }
    // End stops: inelastic, the lens rests against them until pulled back.
    if (position_ > high_stop_) {
      position_ = high_stop_;
      velocity_scaled_ = std::min(velocity_scaled_, 0.0);
    } else if (position_ < low_stop_) {
      position_ = low_stop_;
      velocity_scaled_ = std::max(velocity_scaled_, 0.0);
    }
    return position_;
  }

 private:
  // Force F = kp e + ki integral(e) on the lens x'' = wn^2 (F - x) - 2 zeta wn x' (force in pixels
  // of static deflection), semi-implicit Euler at the step (wn h << 1). The integrator is held
  // while the lens rests against an end stop it is pushed into (anti-windup).
  void advancePi(double drive) {
    const double error = drive - position_;
    const bool at_stop =
        (position_ >= high_stop_ && error > 0.0) || (position_ <= low_stop_ && error < 0.0);
    if (!at_stop) integral_ += error * h_;
    const double force = kp_ * error + ki_ * integral_;
    const double wn = natural_rad_s_;
    double velocity = velocity_scaled_ * wn;
    velocity += h_ * (wn * wn * (force - position_) - 2.0 * damping_ * wn * velocity);
    position_ += h_ * velocity;
    velocity_scaled_ = velocity / wn;
  }

  bool first_order_, pi_;
  double kp_, ki_;
  double h_, rate_limit_px_s_, breakaway_px_, low_stop_, high_stop_;
  double decay_ = 0.0;
  double natural_rad_s_ = 1.0, damping_ = 0.0;
  double integral_ = 0.0;  // the PI loop's integral of the error, px s
  Eigen::Matrix2d transition_ = Eigen::Matrix2d::Identity();
  Eigen::Vector2d input_ = Eigen::Vector2d::Zero();
  double position_ = 0.0, velocity_scaled_ = 0.0;
  bool stuck_ = false;
};

// The Hall reading of one axis and its inverse (monotone over the end stops for c2, c3 within the
// design's ranges).
class HallAxis {
 public:
  HallAxis(double c2, double c3, double scale_px) : c2_(c2), c3_(c3), L_(scale_px) {}
  double reading(double x) const {
    const double u = x / L_;
    return x + L_ * (c2_ * u * u + c3_ * u * u * u);
  }
  double lens(double reading_px) const {
    if (c2_ == 0.0 && c3_ == 0.0) return reading_px;
    double x = reading_px;
    for (int i = 0; i < 20; ++i) {
      const double u = x / L_;
      const double step = (reading(x) - reading_px) / (1.0 + 2.0 * c2_ * u + 3.0 * c3_ * u * u);
      x -= step;
      if (std::abs(step) < 1e-13 * (1.0 + std::abs(x))) break;
    }
    return x;
  }

 private:
  double c2_, c3_, L_;
};

class HallActuatorRunner final : public StabiliserStageRunner {
 public:
  HallActuatorRunner(const HallActuatorValues& p, const StabiliserModel& model, const StabiliserRunContext& context)
      : delay_steps_(static_cast<std::size_t>(std::lround(p.delay_s * (1.0 / context.step_s)))) {
    const HallActuatorValues& v = p;
    const TravelValues& t = model.get<TravelValues>();
    auto px = [&](double deg) { return context.focal_px * std::tan(deg * kDegToRad); };
    const double x_pos = px(t.x_positive_deg), x_neg = px(t.x_negative_deg);
    const double y_pos = px(t.y_positive_deg), y_neg = px(t.y_negative_deg);
    hall_ = {HallAxis(v.hall_c2, v.hall_c3, std::max(x_pos, x_neg)), HallAxis(v.hall_c2, v.hall_c3, std::max(y_pos, y_neg))};
    const double margin = v.end_stop_margin;
    const double rate_limit_px_s = context.focal_px * v.rate_limit_deg_s * kDegToRad;
    const double breakaway_px = v.stiction_fraction * 0.5 * (x_pos + x_neg);
    axes_ = {LensAxis(v, context.step_s, rate_limit_px_s, breakaway_px, hall_[0].reading(-margin * x_neg),
                      hall_[0].reading(margin * x_pos)),
             LensAxis(v, context.step_s, rate_limit_px_s, breakaway_px, hall_[1].reading(-margin * y_neg),
                      hall_[1].reading(margin * y_pos))};
  }
  void reset(StabiliserSignal&) override {
    pending_.assign(delay_steps_ + 1, Eigen::Vector2d::Zero());
    for (LensAxis& axis : axes_) axis.reset();
  }
  void advance(StabiliserSignal& signal) override {
    // The command of delay_steps_ + 1 steps ago: the controller's updates come after the lens
    // moved in the step they sampled.
    pending_.push_back(signal.command_px);
    const Eigen::Vector2d command = pending_.front();
    pending_.pop_front();
    // The loop drives the (noisy) reading to the command: the lens sits where h(x) = command.
    const double reading_x = axes_[0].advance(command.x() - signal.hall_noise_px.x());
    const double reading_y = axes_[1].advance(command.y() - signal.hall_noise_px.y());
    signal.actuator_px = Eigen::Vector2d(reading_x, reading_y);
    signal.lens_px = Eigen::Vector2d(hall_[0].lens(reading_x), hall_[1].lens(reading_y));
  }

 private:
  std::size_t delay_steps_;
  std::deque<Eigen::Vector2d> pending_;
  std::vector<HallAxis> hall_;
  std::vector<LensAxis> axes_;
};

}  // namespace

const StabiliserStage& hallActuatorStage() {
  static const StabiliserStage stage{
      "hall_actuator",
      "the command late by delay_s, then the lens' position loop (first or second order, or a PI "
      "loop around a spring-mass lens; bandwidth_hz, damping, slew limit, stiction, end stops) on "
      "a Hall reading with quadratic and cubic terms",
      false,
      {},
      {"hall_actuator"},
      stage_numerics::make<HallActuatorValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        HallActuatorValues v = valuesAs<HallActuatorValues>(own);
        stabiliser_file_fields::writeValueMap(out, "hall_actuator", fields(v));
      },
      [](const YAML::Node& s, StageValues& own) {
        return stabiliser_file_fields::readValueMap(s, "hall_actuator", fields(valuesAs<HallActuatorValues>(own)));
      },
      [](const StageValues& own, const StabiliserModel& model) {
        std::ostringstream why;
        const HallActuatorValues& v = valuesAs<HallActuatorValues>(own);
        if (v.order != "first" && v.order != "second" && v.order != "pi")
          why << "hall_actuator.order: must be first, second or pi (got '" << v.order << "')";
        else if (!(v.pi_kp > 0.0 && v.pi_ki >= 0.0))
          why << "hall_actuator: pi_kp must be positive and pi_ki not negative";
        else if (!(v.delay_s >= 0.0 && v.delay_s < 1.0 && v.bandwidth_hz > 0.0 && v.damping > 0.0 &&
                   v.rate_limit_deg_s >= 0.0 && v.stiction_fraction >= 0.0 && v.end_stop_margin >= 1.0))
          why << "hall_actuator: delay in [0, 1) s, bandwidth and damping positive, slew limit and "
                 "stiction not negative, end_stop_margin >= 1";
        else if (!(std::abs(v.hall_c2) <= 0.2 && std::abs(v.hall_c3) <= 0.3))
          why << "hall_actuator: hall_c2 within +-0.2 and hall_c3 within +-0.3 (a monotone reading)";
        else if (!model.has("travel"))
          why << "hall_actuator: needs the travel stage (its stroke sets the end stops)";
        return why.str();
      },
      stage_numerics::runner<HallActuatorRunner, HallActuatorValues>,
      [](const StageValues& own) {
        return "hall_actuator:" + valuesAs<HallActuatorValues>(own).order;
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
