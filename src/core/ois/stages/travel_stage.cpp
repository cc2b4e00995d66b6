// The travel stage of a sampled controller: the stroke the command is limited to, per axis and
// direction (asymmetric when they differ), hard (a box or an ellipse) or soft (limit x tanh), the
// anti-windup of the intended-motion angle while the command is beyond the hard stroke (none: it
// winds up; clamp: held at the stroke; back_calculation: pulled back at a rate), and a DAC that
// quantises the command to (x_positive + x_negative) stroke / 2^bits, or to a step given as an
// angle.
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

stabiliser_file_fields::ValueFields fields(TravelValues& v) {
  return {{{"x_positive_deg", &v.x_positive_deg},
           {"x_negative_deg", &v.x_negative_deg},
           {"y_positive_deg", &v.y_positive_deg},
           {"y_negative_deg", &v.y_negative_deg},
           {"back_calculation_rate_per_s", &v.back_calculation_rate_per_s},
           {"quantiser_bits", &v.quantiser_bits},
           {"quantiser_lsb_deg", &v.quantiser_lsb_deg}},
          {{"shape", &v.shape}, {"anti_windup", &v.anti_windup}},
          {}};
}

class TravelRunner final : public StabiliserStageRunner {
 public:
  TravelRunner(const TravelValues& p, const StabiliserModel& model, const StabiliserRunContext& context)
      : v_(p),
        elliptic_(v_.shape == "ellipse" || v_.shape == "soft_ellipse"),
        soft_(v_.shape == "soft_box" || v_.shape == "soft_ellipse"),
        anti_windup_(v_.anti_windup != "none") {
    const double T = stage_numerics::controlPeriod(model, context);
    auto px = [&](double deg) { return context.focal_px * std::tan(deg * stage_numerics::kDegToRad); };
    x_pos_ = px(v_.x_positive_deg), x_neg_ = px(v_.x_negative_deg);
    y_pos_ = px(v_.y_positive_deg), y_neg_ = px(v_.y_negative_deg);
    if (v_.quantiser_bits > 0.0) lsb_px_ = (x_pos_ + x_neg_) / std::ldexp(1.0, static_cast<int>(v_.quantiser_bits));
    if (v_.quantiser_lsb_deg > 0.0)
      lsb_px_ = context.focal_px * std::tan(v_.quantiser_lsb_deg * stage_numerics::kPi / 180.0);
    fraction_ = v_.anti_windup == "clamp" ? 1.0 : -std::expm1(-v_.back_calculation_rate_per_s * T);
  }
  void reset(StabiliserSignal& signal) override {
    signal.angle_correction_rad.setZero();
    signal.excursion.setZero();
  }
  void advance(StabiliserSignal& signal) override {
    if (!signal.control_tick) return;
    Eigen::Vector2d raw = signal.raw_command_px;
    if (anti_windup_ && signal.gain_scale > 0.05) {
      const Eigen::Vector2d limited = hardStroke(raw);
      if (limited != raw) {
        // The angle that would command the stroke itself; the intended-motion state is moved
        // (part of the way) there, so it does not wind up beyond what the lens can do.
        const Eigen::Vector2d& gain = signal.command_gain_px;
        const Eigen::Vector2d target(-std::atan(limited.y() / gain.y()), std::atan(limited.x() / gain.x()));
        signal.angle_correction_rad = fraction_ * (target - signal.angle_rad);
        const Eigen::Vector2d moved = signal.angle_rad + signal.angle_correction_rad;
        raw = Eigen::Vector2d(gain.x() * std::tan(moved.y()), -gain.y() * std::tan(moved.x()));
      }
    }
    signal.excursion = Eigen::Vector2d(std::abs(raw.x()) / limitX(raw.x()), std::abs(raw.y()) / limitY(raw.y()));
    Eigen::Vector2d command = stroked(raw);
    if (lsb_px_ > 0.0)
      command = Eigen::Vector2d(lsb_px_ * std::round(command.x() / lsb_px_), lsb_px_ * std::round(command.y() / lsb_px_));
    signal.raw_command_px = raw;
    signal.command_px = command;
  }

 private:
  double limitX(double x) const { return x >= 0.0 ? x_pos_ : x_neg_; }
  double limitY(double y) const { return y >= 0.0 ? y_pos_ : y_neg_; }
  Eigen::Vector2d hardStroke(const Eigen::Vector2d& c) const {
    const double lx = limitX(c.x()), ly = limitY(c.y());
    if (elliptic_) {
      const double r = std::hypot(c.x() / lx, c.y() / ly);
      return r > 1.0 ? Eigen::Vector2d(c / r) : c;
    }
    return Eigen::Vector2d(std::clamp(c.x(), -lx, lx), std::clamp(c.y(), -ly, ly));
  }
  Eigen::Vector2d stroked(const Eigen::Vector2d& c) const {
    if (!soft_) return hardStroke(c);
    const double lx = limitX(c.x()), ly = limitY(c.y());
    if (!elliptic_) return Eigen::Vector2d(lx * std::tanh(c.x() / lx), ly * std::tanh(c.y() / ly));
    const double r = std::hypot(c.x() / lx, c.y() / ly);
    return r > 1e-12 ? Eigen::Vector2d(c * (std::tanh(r) / r)) : c;
  }

  TravelValues v_;
  bool elliptic_, soft_, anti_windup_;
  double x_pos_, x_neg_, y_pos_, y_neg_;  // px
  double lsb_px_ = 0.0;
  double fraction_;  // of the way back to the stroke per update
};

}  // namespace

const StabiliserStage& travelStage() {
  static const StabiliserStage stage{
      "travel",
      "the stroke per axis and direction (box, ellipse, soft_box, soft_ellipse; deg), the "
      "intended-motion angle's anti-windup (none, clamp, back_calculation) and a DAC of "
      "quantiser_bits or a step of quantiser_lsb_deg",
      false,
      {},
      {"travel"},
      stage_numerics::make<TravelValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        TravelValues v = valuesAs<TravelValues>(own);
        stabiliser_file_fields::writeValueMap(out, "travel", fields(v));
      },
      [](const YAML::Node& s, StageValues& own) {
        return stabiliser_file_fields::readValueMap(s, "travel", fields(valuesAs<TravelValues>(own)));
      },
      [](const StageValues& own, const StabiliserModel&) {
        std::ostringstream why;
        const TravelValues& v = valuesAs<TravelValues>(own);
        if (v.shape != "box" && v.shape != "ellipse" && v.shape != "soft_box" && v.shape != "soft_ellipse")
          why << "travel.shape: must be box, ellipse, soft_box or soft_ellipse (got '" << v.shape << "')";
        else if (v.anti_windup != "none" && v.anti_windup != "clamp" && v.anti_windup != "back_calculation")
          why << "travel.anti_windup: must be none, clamp or back_calculation (got '" << v.anti_windup << "')";
        else if (!(std::min({v.x_positive_deg, v.x_negative_deg, v.y_positive_deg,
                             v.y_negative_deg}) > 0.0 &&
                   std::max({v.x_positive_deg, v.x_negative_deg, v.y_positive_deg,
                             v.y_negative_deg}) < 45.0))
          why << "travel: the stroke must be in (0, 45) deg in every direction";
        else if (!(v.back_calculation_rate_per_s > 0.0) ||
                 !(v.quantiser_bits >= 0.0 && v.quantiser_bits <= 24.0 && v.quantiser_bits == std::floor(v.quantiser_bits)))
          why << "travel: back_calculation_rate_per_s must be positive, quantiser_bits a whole 0..24";
        else if (!(v.quantiser_lsb_deg >= 0.0 && v.quantiser_lsb_deg < 1.0) ||
                 (v.quantiser_lsb_deg > 0.0 && v.quantiser_bits > 0.0))
          why << "travel: quantiser_lsb_deg must be in [0, 1) deg, and not with quantiser_bits";
        return why.str();
      },
      stage_numerics::runner<TravelRunner, TravelValues>,
      [](const StageValues& own) { return "travel:" + valuesAs<TravelValues>(own).shape; },
      nullptr};
  return stage;
}

}  // namespace deep_ois
