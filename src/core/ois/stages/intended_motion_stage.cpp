// The intended-motion stage of a sampled controller: the angle the lens is asked to cancel, per
// axis (as real controllers run them), by an estimator of one of five kinds, and the command that
// cancels it. Its corner (bandwidth) is multiplied by motion_mode's release and by the excursion
// against the stroke (1 + excursion_gain e^excursion_power per axis, e from travel's last update);
// its gain by motion_mode's. Travel's anti-windup moves its angle (applied at the next update).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/intended_motion_tracker.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

using stage_numerics::kPi;

// A re-centring faster than this is no stabilisation any more; capping the effective corner
// (excursion x release factors) also keeps the explicit estimator updates well inside stability
// at the slowest loop rate (500 Hz: w T <= 0.25).
constexpr double kMaxEffectiveCornerHz = 20.0;

enum class Kind { kHighpass1, kHighpass2, kVelocityLoop, kKalman, kAlphaBeta };
const char* const kKinds[] = {"highpass_first_order", "highpass_second_order", "velocity_loop",
                              "kalman_cv", "alpha_beta"};

int kindIndex(const std::string& word) {
  for (int k = 0; k < 5; ++k)
    if (word == kKinds[k]) return k;
  return -1;
}

stabiliser_file_fields::ValueFields fields(IntendedMotionValues& v) {
  return {{{"corner_hz", &v.corner_hz},
           {"damping", &v.damping},
           {"rate_corner_hz", &v.rate_corner_hz},
           {"excursion_gain", &v.excursion_gain},
           {"excursion_power", &v.excursion_power},
           {"gain_x", &v.gain_x},
           {"gain_y", &v.gain_y},
           {"manoeuvre_deg", &v.manoeuvre_deg},
           {"manoeuvre_factor", &v.manoeuvre_factor}},
          {{"kind", &v.kind}},
          {}};
}

class IntendedMotionRunner final : public StabiliserStageRunner {
 public:
  IntendedMotionRunner(const IntendedMotionValues& p, const StabiliserModel& model, const StabiliserRunContext& context)
      : v_(p),
        kind_(static_cast<Kind>(kindIndex(p.kind))),
        T_(stage_numerics::controlPeriod(model, context)),
        focal_px_(context.focal_px) {}
  void reset(StabiliserSignal& signal) override {
    theta_.setZero();
    velocity_.setZero();
    integrated_.setZero();
    intended_.setZero();
    for (Eigen::Matrix2d& p : covariance_) p = 1e-8 * Eigen::Matrix2d::Identity();
    signal.angle_rad.setZero();
  }
  void advance(StabiliserSignal& signal) override {
    if (!signal.control_tick) return;
    // Travel's anti-windup of the last update moved the cancelled angle (and the integral it is
    // taken from), so the state does not wind up beyond what the lens can do.
    theta_ += signal.angle_correction_rad;
    integrated_ += signal.angle_correction_rad;
    signal.angle_correction_rad.setZero();
    // theta_x drives lens y, theta_y lens x.
    Eigen::Vector2d multiplier = Eigen::Vector2d::Constant(signal.corner_scale);
    if (v_.excursion_gain > 0.0) {
      multiplier(0) *= 1.0 + v_.excursion_gain * std::pow(signal.excursion.y(), v_.excursion_power);
      multiplier(1) *= 1.0 + v_.excursion_gain * std::pow(signal.excursion.x(), v_.excursion_power);
    }
    for (int a = 0; a < 2; ++a) advanceAxis(a, signal.sampled_rate_rad_s(a), multiplier(a));
    // s = f g (tan theta_y, -tan theta_x): the sign convention of the simulator's OisModel.
    const double common = signal.gain_scale;
    signal.command_gain_px = Eigen::Vector2d(focal_px_ * common * v_.gain_x, focal_px_ * common * v_.gain_y);
    signal.angle_rad = theta_;
    signal.raw_command_px = Eigen::Vector2d(signal.command_gain_px.x() * std::tan(theta_.y()),
                                            -signal.command_gain_px.y() * std::tan(theta_.x()));
  }

 private:
  // y' = u - w y over the period for a held u: exact.
  double leak(double y, double u, double w) const {
    return w > 0.0 ? std::exp(-w * T_) * y - std::expm1(-w * T_) / w * u : y + T_ * u;
  }

  void advanceAxis(int a, double rate, double multiplier) {
    const double corner_hz = std::min(v_.corner_hz * multiplier, kMaxEffectiveCornerHz);
    const double w = 2.0 * kPi * corner_hz;
    switch (kind_) {
      case Kind::kHighpass1:
        theta_(a) = leak(theta_(a), rate, w);
        break;
      case Kind::kHighpass2:
        // theta = angle - p, p'' = w^2 theta - 2 zeta w p' (p tracks the angle with a second-order
        // low-pass): semi-implicit Euler, v the intended rate.
        velocity_(a) += T_ * (w * w * theta_(a) - 2.0 * v_.damping * w * velocity_(a));
        theta_(a) += T_ * (rate - velocity_(a));
        break;
      case Kind::kVelocityLoop: {
        // The intended rate is the rate's low-pass; the rest is integrated with a leak.
        const double rate_corner_hz = std::min(v_.rate_corner_hz * multiplier, kMaxEffectiveCornerHz);
        velocity_(a) += -std::expm1(-2.0 * kPi * rate_corner_hz * T_) * (rate - velocity_(a));
        theta_(a) = leak(theta_(a), rate - velocity_(a), w);
        break;
      }
      case Kind::kAlphaBeta: {
        // Fixed gains of a second-order tracker: s^2 + (alpha / T) s + beta / T^2 =
        // s^2 + 2 zeta w s + w^2. theta = angle - intended (the residual).
        const double alpha = 2.0 * v_.damping * w * T_;
        const double beta = w * w * T_ * T_;
        const double predicted = theta_(a) + T_ * (rate - velocity_(a));
        velocity_(a) += beta / T_ * predicted;
        theta_(a) = (1.0 - alpha) * predicted;
        break;
      }
      case Kind::kKalman: {
        // The Kalman estimator (intended_motion_tracker.h); a bandwidth multiplier m scales q by m^4.
        IntendedMotionTrackerStep step;
        step.step_s = T_;
        step.bandwidth_hz = v_.corner_hz;
        step.process_noise_scale = std::pow(w / (2.0 * kPi * v_.corner_hz), 4);
        if (v_.manoeuvre_deg > 0.0) {
          step.manoeuvre_rad = v_.manoeuvre_deg * kPi / 180.0;
          step.manoeuvre_factor = v_.manoeuvre_factor;
        }
        integrated_(a) += T_ * rate;
        Eigen::Vector2d intended = intended_.col(a);
        advanceIntendedMotion(step, integrated_(a), intended, covariance_[a]);
        intended_.col(a) = intended;
        theta_(a) = integrated_(a) - intended(0);
        break;
      }
    }
  }

  IntendedMotionValues v_;
  Kind kind_;
  double T_, focal_px_;
  Eigen::Vector2d theta_ = Eigen::Vector2d::Zero();     // the cancelled angle (rad)
  Eigen::Vector2d velocity_ = Eigen::Vector2d::Zero();  // intended rate (highpass2, velocity, a-b)
  // Kalman: integrated angle, intended (angle, rate) per axis (columns), covariance.
  Eigen::Vector2d integrated_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d intended_ = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d covariance_[2];
};

}  // namespace

const StabiliserStage& intendedMotionStage() {
  static const StabiliserStage stage{
      "intended_motion",
      "the angle to cancel by an estimator (highpass_first_order, highpass_second_order, "
      "velocity_loop, kalman_cv with a manoeuvre gate, alpha_beta) with excursion-dependent "
      "corner, and its gain per axis",
      false,
      {},
      {"intended_motion"},
      stage_numerics::make<IntendedMotionValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        IntendedMotionValues v = valuesAs<IntendedMotionValues>(own);
        stabiliser_file_fields::writeValueMap(out, "intended_motion", fields(v));
      },
      [](const YAML::Node& s, StageValues& own) {
        return stabiliser_file_fields::readValueMap(s, "intended_motion", fields(valuesAs<IntendedMotionValues>(own)));
      },
      [](const StageValues& own, const StabiliserModel& model) {
        std::ostringstream why;
        const IntendedMotionValues& v = valuesAs<IntendedMotionValues>(own);
        if (kindIndex(v.kind) < 0)
          why << "intended_motion.kind: unknown '" << v.kind << "'";
        else if (!((v.corner_hz > 0.0 ||
                    (v.corner_hz == 0.0 && v.kind == "highpass_first_order")) &&
                   v.damping > 0.0 && v.rate_corner_hz > 0.0 && v.excursion_gain >= 0.0 &&
                   v.excursion_power > 0.0))
          why << "intended_motion: corners, damping and excursion_power must be positive "
                 "(corner_hz 0: a highpass_first_order that never re-centres)";
        else if (!(v.manoeuvre_deg >= 0.0 && v.manoeuvre_factor >= 1.0))
          why << "intended_motion: manoeuvre_deg must be >= 0 (0 = no gate), manoeuvre_factor >= 1";
        else if (!(std::isfinite(v.gain_x) && std::isfinite(v.gain_y)))
          why << "intended_motion: gain_x and gain_y must be finite";
        else if (!model.has("gyro_loop") || !model.has("travel"))
          why << "intended_motion: needs the gyro_loop and travel stages";
        return why.str();
      },
      stage_numerics::runner<IntendedMotionRunner, IntendedMotionValues>,
      [](const StageValues& own) {
        return "intended_motion:" + valuesAs<IntendedMotionValues>(own).kind;
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
