#include "deep_ois/core/sim/stabiliser_design_runner.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/common/matrix_exponential.h"
#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/sim/intended_motion_tracker.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
// A re-centring faster than this is no stabilisation any more; capping the effective corner
// (excursion x release factors) also keeps the explicit estimator updates well inside stability
// at the slowest loop rate (500 Hz: w T <= 0.25).
constexpr double kMaxEffectiveCornerHz = 20.0;

// Lens-plane limits in pixels per axis and direction.
struct StrokePx {
  double x_pos, x_neg, y_pos, y_neg;
  double limitX(double x) const { return x >= 0.0 ? x_pos : x_neg; }
  double limitY(double y) const { return y >= 0.0 ? y_pos : y_neg; }
};

// The angle to cancel (rad, about the gyro's x and y), per estimator class. Each axis on its own,
// as real controllers run them.
class Estimator {
 public:
  Estimator(const EstimatorStage& stage, double period_s) : stage_(stage), T_(period_s) {
    for (Eigen::Matrix2d& p : covariance_) p = 1e-8 * Eigen::Matrix2d::Identity();
  }

  // `rate`: the sampled gyro rate over the period (rad/s); `multiplier`: the corner (bandwidth)
  // multiplier per axis from the excursion and the mode, >= 1.
  void advance(const Eigen::Vector2d& rate, const Eigen::Vector2d& multiplier) {
    for (int a = 0; a < 2; ++a) {
      const double corner_hz = std::min(stage_.corner_hz * multiplier(a), kMaxEffectiveCornerHz);
      const double w = 2.0 * kPi * corner_hz;
      switch (stage_.kind) {
        case EstimatorKind::kHighpass1:
          theta_(a) = leak(theta_(a), rate(a), w);
          break;
        case EstimatorKind::kHighpass2: {
          // theta = angle - p, p'' = w^2 theta - 2 zeta w p' (p tracks the angle with a second-order
          // low-pass): semi-implicit Euler, v the intended rate.
          velocity_(a) += T_ * (w * w * theta_(a) - 2.0 * stage_.damping * w * velocity_(a));
          theta_(a) += T_ * (rate(a) - velocity_(a));
          break;
        }
        case EstimatorKind::kVelocityLoop: {
          // The intended rate is the rate's low-pass; the rest is integrated with a leak.
          const double rate_corner_hz =
              std::min(stage_.rate_corner_hz * multiplier(a), kMaxEffectiveCornerHz);
          velocity_(a) += -std::expm1(-2.0 * kPi * rate_corner_hz * T_) * (rate(a) - velocity_(a));
          theta_(a) = leak(theta_(a), rate(a) - velocity_(a), w);
          break;
        }
        case EstimatorKind::kAlphaBeta: {
          // Fixed gains of a second-order tracker: s^2 + (alpha / T) s + beta / T^2 =
          // s^2 + 2 zeta w s + w^2. theta = angle - intended (the residual).
          const double alpha = 2.0 * stage_.damping * w * T_;
          const double beta = w * w * T_ * T_;
          const double predicted = theta_(a) + T_ * (rate(a) - velocity_(a));
          velocity_(a) += beta / T_ * predicted;
          theta_(a) = (1.0 - alpha) * predicted;
          break;
        }
        case EstimatorKind::kKalman:
          advanceKalman(a, rate(a), w / (2.0 * kPi * stage_.corner_hz));
          break;
      }
    }
  }

  const Eigen::Vector2d& cancelled() const { return theta_; }

  // Anti-windup: moves the cancelled angle by `delta` (rad) by moving the integrated angle.
  void shift(const Eigen::Vector2d& delta) {
    theta_ += delta;
    integrated_ += delta;
  }

 private:
  // y' = u - w y over the period for a held u: exact.
  double leak(double y, double u, double w) const {
    return std::exp(-w * T_) * y - std::expm1(-w * T_) / w * u;
  }

  // The Kalman estimator (intended_motion_tracker.h); a bandwidth multiplier m scales q by m^4.
  void advanceKalman(int a, double rate, double m) {
    IntendedMotionTrackerStep step;
    step.step_s = T_;
    step.bandwidth_hz = stage_.corner_hz;
    step.process_noise_scale = std::pow(m, 4);
    integrated_(a) += T_ * rate;
    Eigen::Vector2d intended = intended_.col(a);
    advanceIntendedMotion(step, integrated_(a), intended, covariance_[a]);
    intended_.col(a) = intended;
    theta_(a) = integrated_(a) - intended(0);
  }

  const EstimatorStage& stage_;
  double T_;
  Eigen::Vector2d theta_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d velocity_ = Eigen::Vector2d::Zero();  // intended rate (highpass2, velocity, a-b)
  // Kalman: integrated angle, intended (angle, rate) per axis (columns), covariance.
  Eigen::Vector2d integrated_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d intended_ = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d covariance_[2];
};

// A first-order low-pass of the pan/tilt rate magnitude (the gain schedule's view of how much the
// camera moves).
class RateLevel {
 public:
  explicit RateLevel(double time_constant_s) : time_constant_s_(time_constant_s) {}
  double advance(double magnitude, double period_s) {
    level_ += -std::expm1(-period_s / time_constant_s_) * (magnitude - level_);
    return level_;
  }

 private:
  double time_constant_s_;
  double level_ = 0.0;
};

// The controller of a design: the estimator and everything up to the quantised command.
class DesignController {
 public:
  DesignController(const StabiliserDesign& design, double focal_px, double period_s)
      : design_(design),
        focal_px_(focal_px),
        T_(period_s),
        estimator_(design.estimator, period_s),
        schedule_level_(design.gain.schedule_time_constant_s) {
    const StrokeStage& s = design.stroke;
    auto px = [focal_px](double deg) { return focal_px * std::tan(deg * kDeg); };
    stroke_ = {px(s.x_positive_deg), px(s.x_negative_deg), px(s.y_positive_deg), px(s.y_negative_deg)};
    if (design.output.quantiser_bits > 0) {
      lsb_px_ = (stroke_.x_pos + stroke_.x_neg) / std::ldexp(1.0, design.output.quantiser_bits);
    }
  }

  const StrokePx& stroke() const { return stroke_; }
  const Eigen::Vector2d& command() const { return command_; }

  void advance(const Eigen::Vector2d& rate) {
    const double magnitude = rate.norm();
    // Mode detection (hysteresis) and what it does.
    double release = 1.0;
    if (design_.mode.action != ModeAction::kNone) {
      // A pan is a sustained rate: the rate vector's low-pass (the shake averages out in it).
      sustained_rate_ += -std::expm1(-T_ / design_.mode.time_constant_s) * (rate - sustained_rate_);
      const double level = sustained_rate_.norm();
      if (!panning_ && level > design_.mode.threshold_rad_s) panning_ = true;
      if (panning_ && level < 0.7 * design_.mode.threshold_rad_s) panning_ = false;
      if (design_.mode.action == ModeAction::kRelease && panning_) release = design_.mode.release_factor;
      if (design_.mode.action == ModeAction::kHold) {
        hold_gain_ += -std::expm1(-T_ / design_.mode.hold_time_constant_s) *
                      ((panning_ ? 0.0 : 1.0) - hold_gain_);
      }
    }
    double schedule = 1.0;
    if (design_.gain.schedule_depth > 0.0) {
      const double level = schedule_level_.advance(magnitude, T_);
      const double x = std::clamp(
          (level - design_.gain.schedule_start_rad_s) / design_.gain.schedule_span_rad_s, 0.0, 1.0);
      schedule = 1.0 - design_.gain.schedule_depth * x;
    }
    // Excursion-dependent centring: from the last command's excursion against the stroke on its
    // side (theta_x drives lens y, theta_y lens x).
    Eigen::Vector2d multiplier = Eigen::Vector2d::Constant(release);
    if (design_.estimator.excursion_gain > 0.0) {
      const double ex = std::abs(raw_.x()) / stroke_.limitX(raw_.x());
      const double ey = std::abs(raw_.y()) / stroke_.limitY(raw_.y());
      multiplier(0) *= 1.0 + design_.estimator.excursion_gain * std::pow(ey, design_.estimator.excursion_power);
      multiplier(1) *= 1.0 + design_.estimator.excursion_gain * std::pow(ex, design_.estimator.excursion_power);
    }
    estimator_.advance(rate, multiplier);

    // s = f g (tan theta_y, -tan theta_x): see OisModel's sign derivation (ois_model.cpp).
    const double common = hold_gain_ * schedule;
    const Eigen::Vector2d scale_px(focal_px_ * common * design_.gain.gain_x,
                                   focal_px_ * common * design_.gain.gain_y);
    auto rawCommand = [&] {
      const Eigen::Vector2d& theta = estimator_.cancelled();
      return Eigen::Vector2d(scale_px.x() * std::tan(theta.y()), -scale_px.y() * std::tan(theta.x()));
    };
    raw_ = rawCommand();
    const AntiWindupKind aw = design_.anti_windup.kind;
    if (aw != AntiWindupKind::kNone && common > 0.05) {
      const Eigen::Vector2d limited = hardStroke(raw_);
      if (limited != raw_) {
        // The angle that would command the stroke itself; the state is moved (part of the way)
        // there, so it does not wind up beyond what the lens can do.
        const Eigen::Vector2d target(-std::atan(limited.y() / scale_px.y()),
                                     std::atan(limited.x() / scale_px.x()));
        const double fraction =
            aw == AntiWindupKind::kClamp
                ? 1.0
                : -std::expm1(-design_.anti_windup.back_calculation_rate_per_s * T_);
        estimator_.shift(fraction * (target - estimator_.cancelled()));
        raw_ = rawCommand();
      }
    }
    command_ = stroked(raw_);
    if (lsb_px_ > 0.0) {
      command_ = Eigen::Vector2d(lsb_px_ * std::round(command_.x() / lsb_px_),
                                 lsb_px_ * std::round(command_.y() / lsb_px_));
    }
  }

 private:
  Eigen::Vector2d hardStroke(const Eigen::Vector2d& c) const {
    const double lx = stroke_.limitX(c.x()), ly = stroke_.limitY(c.y());
    const StrokeKind kind = design_.stroke.kind;
    if (kind == StrokeKind::kEllipse || kind == StrokeKind::kSoftEllipse) {
      const double r = std::hypot(c.x() / lx, c.y() / ly);
      return r > 1.0 ? Eigen::Vector2d(c / r) : c;
    }
    return Eigen::Vector2d(std::clamp(c.x(), -lx, lx), std::clamp(c.y(), -ly, ly));
  }

  Eigen::Vector2d stroked(const Eigen::Vector2d& c) const {
    const double lx = stroke_.limitX(c.x()), ly = stroke_.limitY(c.y());
    switch (design_.stroke.kind) {
      case StrokeKind::kBox:
      case StrokeKind::kEllipse:
        return hardStroke(c);
      case StrokeKind::kSoftBox:
        return Eigen::Vector2d(lx * std::tanh(c.x() / lx), ly * std::tanh(c.y() / ly));
      case StrokeKind::kSoftEllipse: {
        const double r = std::hypot(c.x() / lx, c.y() / ly);
        return r > 1e-12 ? Eigen::Vector2d(c * (std::tanh(r) / r)) : c;
      }
    }
    return c;
  }

  const StabiliserDesign& design_;
  double focal_px_;
  double T_;
  StrokePx stroke_{};
  double lsb_px_ = 0.0;
  Estimator estimator_;
  RateLevel schedule_level_;
  Eigen::Vector2d sustained_rate_ = Eigen::Vector2d::Zero();
  bool panning_ = false;
  double hold_gain_ = 1.0;
  Eigen::Vector2d raw_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d command_ = Eigen::Vector2d::Zero();
};

// One axis of the lens under its position loop, in Hall-reading units (pixels as the loop sees
// them): linear dynamics discretised exactly for a command held over a physics step, then the slew
// limit, stiction (stick below the breakaway error, slide against half of it) and the end stops.
class Actuator {
 public:
  Actuator(const ActuatorStage& stage, double step_s, double rate_limit_px_s, double breakaway_px,
           double low_stop, double high_stop)
      : first_order_(stage.order == ActuatorOrder::kFirst),
        h_(step_s),
        rate_limit_px_s_(rate_limit_px_s),
        breakaway_px_(breakaway_px),
        low_stop_(low_stop),
        high_stop_(high_stop),
        stuck_(breakaway_px > 0.0) {  // at rest: held by its stiction until the loop pulls
    const double wh = 2.0 * kPi * stage.bandwidth_hz * step_s;
    if (first_order_) {
      decay_ = std::exp(-wh);
    } else {
      // State (x, x' / wn): d/dt = wn [[0, 1], [-1, -2 zeta]] + wn (0, 1) u.
      Eigen::Matrix3d augmented;
      augmented << 0.0, wh, 0.0, -wh, -2.0 * stage.damping * wh, wh, 0.0, 0.0, 0.0;
      const Eigen::Matrix3d e = matrixExponential(augmented);
      transition_ = e.topLeftCorner<2, 2>();
      input_ = e.topRightCorner<2, 1>();
      natural_rad_s_ = 2.0 * kPi * stage.bandwidth_hz;
    }
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
    if (first_order_) {
      position_ = drive + (position_ - drive) * decay_;
    } else {
      const Eigen::Vector2d state = transition_ * Eigen::Vector2d(position_, velocity_scaled_) + input_ * drive;
      position_ = state.x();
      velocity_scaled_ = state.y();
    }
    if (rate_limit_px_s_ > 0.0) {
      const double step = rate_limit_px_s_ * h_;
      if (std::abs(position_ - before) > step) position_ = before + std::copysign(step, position_ - before);
      if (!first_order_ && std::abs(velocity_scaled_ * natural_rad_s_) > rate_limit_px_s_) {
        velocity_scaled_ = std::copysign(rate_limit_px_s_ / natural_rad_s_, velocity_scaled_);
      }
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
  bool first_order_;
  double h_, rate_limit_px_s_, breakaway_px_, low_stop_, high_stop_;
  double decay_ = 0.0;
  double natural_rad_s_ = 1.0;
  Eigen::Matrix2d transition_ = Eigen::Matrix2d::Identity();
  Eigen::Vector2d input_ = Eigen::Vector2d::Zero();
  double position_ = 0.0, velocity_scaled_ = 0.0;
  bool stuck_ = false;
};

// The Hall reading h(x) = x + c2 L (x/L)^2 + c3 L (x/L)^3 of one axis and its inverse (monotone
// over the end stops for the stated ranges of c2, c3).
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

}  // namespace

LensShiftGrid runDesign(const StabiliserDesign& design, double focal_px, double start_s, int steps,
                        const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                        std::mt19937* noise) {
  const std::string problem = design.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser design: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || steps < 1) {
    throw std::invalid_argument("runDesign: focal_px must be positive and steps at least 1");
  }
  const double h = 1.0 / kDesignPhysicsRateHz;
  const int tick = static_cast<int>(std::lround(kDesignPhysicsRateHz / design.loop.rate_hz));
  DesignController controller(design, focal_px, tick * h);
  const StrokePx& stroke = controller.stroke();

  // Hall sensor and actuator per axis, in reading units; the end stops at margin x stroke.
  const HallAxis hall_x(design.hall.c2, design.hall.c3, std::max(stroke.x_pos, stroke.x_neg));
  const HallAxis hall_y(design.hall.c2, design.hall.c3, std::max(stroke.y_pos, stroke.y_neg));
  const double margin = design.actuator.end_stop_margin;
  const double rate_limit_px_s = focal_px * design.actuator.rate_limit_deg_s * kDeg;
  const double breakaway_px = design.actuator.stiction_fraction * 0.5 * (stroke.x_pos + stroke.x_neg);
  Actuator actuator_x(design.actuator, h, rate_limit_px_s, breakaway_px,
                      hall_x.reading(-margin * stroke.x_neg), hall_x.reading(margin * stroke.x_pos));
  Actuator actuator_y(design.actuator, h, rate_limit_px_s, breakaway_px,
                      hall_y.reading(-margin * stroke.y_neg), hall_y.reading(margin * stroke.y_pos));

  const Eigen::Matrix3d to_gyro = design.mount.cameraToGyro();
  const int delay_steps = static_cast<int>(std::lround(design.output.delay_s * kDesignPhysicsRateHz));
  std::deque<Eigen::Vector2d> pending(static_cast<std::size_t>(delay_steps), Eigen::Vector2d::Zero());

  std::vector<Eigen::Vector2d> shifts(static_cast<std::size_t>(steps) + 1, Eigen::Vector2d::Zero());
  Eigen::Vector2d sum_rate = Eigen::Vector2d::Zero();
  for (int j = 0; j < steps; ++j) {
    // The command the controller holds (zero-order), late by the transport delay.
    pending.push_back(controller.command());
    const Eigen::Vector2d command = pending.front();
    pending.pop_front();
    Eigen::Vector2d hall_noise = Eigen::Vector2d::Zero();
    if (noise && design.hall.noise_px > 0.0) {
      const double nx = gaussian(*noise);
      const double ny = gaussian(*noise);
      hall_noise = design.hall.noise_px * Eigen::Vector2d(nx, ny);
    }
    // The loop drives the (noisy) reading to the command: the lens sits where h(x) = command.
    const double reading_x = actuator_x.advance(command.x() - hall_noise.x());
    const double reading_y = actuator_y.advance(command.y() - hall_noise.y());
    shifts[static_cast<std::size_t>(j) + 1] = Eigen::Vector2d(hall_x.lens(reading_x), hall_y.lens(reading_y));

    // The stabiliser's gyro at the end of the step, in its own (misaligned) frame.
    const Eigen::Vector3d w = to_gyro * angular_velocity_rad_s(start_s + (j + 1) * h);
    Eigen::Vector2d measured = w.head<2>();
    if (noise) {
      const double nx = gaussian(*noise);
      const double ny = gaussian(*noise);
      measured += design.mount.noise_rad_s * Eigen::Vector2d(nx, ny);
    }
    sum_rate += measured;
    if ((j + 1) % tick == 0) {
      controller.advance(design.loop.sampling == GyroSampling::kAveraged ? Eigen::Vector2d(sum_rate / tick)
                                                                         : measured);
      sum_rate.setZero();
    }
  }
  return LensShiftGrid(start_s, kDesignPhysicsRateHz, std::move(shifts));
}

}  // namespace sim
}  // namespace deep_ois
