#include "deep_ois/core/ois/stabiliser_model.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/uniform_grid_interpolation.h"
#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// The leaky integrator y' = w - c y over one step of length h for the mean rate of the step:
// y <- decay y + weight w, exact for a rate held over the step.
double leakDecay(double corner_rad_s, double h) { return std::exp(-corner_rad_s * h); }
double leakWeight(double corner_rad_s, double h) {
  return corner_rad_s > 0.0 ? -std::expm1(-corner_rad_s * h) / corner_rad_s : h;
}

// The command the stroke lets through: per axis for a box, radially for an ellipse; an end stop
// (the nearest point of the stroke) or, soft, stroke * tanh(command / stroke).
Eigen::Vector2d limitToStroke(const Eigen::Vector2d& command, const Eigen::Vector2d& limit_px,
                              bool circular, bool soft) {
  if (soft && !circular) {
    return Eigen::Vector2d(limit_px.x() * std::tanh(command.x() / limit_px.x()),
                           limit_px.y() * std::tanh(command.y() / limit_px.y()));
  }
  if (soft) {
    const double r = std::hypot(command.x() / limit_px.x(), command.y() / limit_px.y());
    return r > 1e-12 ? Eigen::Vector2d(command * (std::tanh(r) / r)) : command;
  }
  if (!circular) {
    return Eigen::Vector2d(std::clamp(command.x(), -limit_px.x(), limit_px.x()),
                           std::clamp(command.y(), -limit_px.y(), limit_px.y()));
  }
  const double r = std::hypot(command.x() / limit_px.x(), command.y() / limit_px.y());
  return r > 1.0 ? Eigen::Vector2d(command / r) : command;
}

// The excursion_v1 set: 10 features per axis (see nonlinearFeatureCount's users below).
constexpr int kExcursionFeaturesPerAxis = 10;
// Leaky integrals of the excursion-weighted command (seconds).
constexpr double kExcursionIntegralTimeConstantsS[] = {0.03, 0.15, 0.6};
// Excursions beyond this many strokes are not weighted further (keeps the powers bounded when a
// badly fitted stroke is small).
constexpr double kMaxExcursion = 3.0;

// The rate_bank_v1 set: leaky integrals of the pan/tilt rate (rad) at these time constants, a
// learned higher-order linear filter from rate to lens beside the chain's own.
constexpr double kRateBankTimeConstantsS[] = {0.002, 0.005, 0.012, 0.03, 0.07, 0.17, 0.4, 1.0, 2.5};
constexpr int kRateBankSize = sizeof(kRateBankTimeConstantsS) / sizeof(double);

bool hasExcursionFeatures(const std::string& set) {
  return set == "excursion_v1" || set == "excursion_rate_v1";
}
bool hasRateBankFeatures(const std::string& set) {
  return set == "rate_bank_v1" || set == "excursion_rate_v1";
}

}  // namespace

int nonlinearFeatureCount(const std::string& feature_set) {
  if (!hasExcursionFeatures(feature_set) && !hasRateBankFeatures(feature_set)) return 0;
  return (hasExcursionFeatures(feature_set) ? 2 * kExcursionFeaturesPerAxis : 0) +
         (hasRateBankFeatures(feature_set) ? 2 * kRateBankSize : 0);
}

StabiliserParameters StabiliserParameters::physicalChain() const {
  StabiliserParameters chain = *this;
  for (const StabiliserStage& stage : stabiliserStages())
    if (stage.clear) stage.clear(&chain);
  return chain;
}

std::string StabiliserParameters::validate() const {
  // Each stage validates its own parameters (core/ois/stabiliser_stage.h); the first problem, in
  // the chain's order, is the answer.
  for (const StabiliserStage& stage : stabiliserStages()) {
    const std::string problem = stage.validate(*this);
    if (!problem.empty()) return problem;
  }
  return {};
}

LensShiftPredictor::LensShiftPredictor(const StabiliserParameters& parameters, double focal_px,
                                       double step_s, double history_s)
    : parameters_(parameters),
      focal_px_(focal_px),
      step_s_(step_s),
      actuator_x_(parameters.actuator_natural_hz, parameters.actuator_damping, step_s, 1.0),
      actuator_y_(parameters.actuator_natural_hz, parameters.actuator_damping, step_s, 1.0) {
  const std::string problem = parameters_.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser model: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || !(step_s > 0.0) || !(history_s > step_s)) {
    throw std::invalid_argument(
        "stabiliser model: focal_px and step_s must be positive and history_s > step_s");
  }
  history_steps_ = static_cast<std::size_t>(std::ceil(history_s / step_s)) + 2;
  const double corner = 2.0 * kPi * parameters_.highpass_corner_hz;
  const double release = 2.0 * kPi * parameters_.pan_release_corner_hz;
  decay_hold_ = leakDecay(corner, step_s);
  weight_hold_ = leakWeight(corner, step_s);
  decay_pan_ = leakDecay(release, step_s);
  weight_pan_ = leakWeight(release, step_s);
  pan_smoothing_ = -std::expm1(-step_s / parameters_.pan_detection_time_constant_s);
  stroke_px_ = Eigen::Vector2d(focal_px * std::tan(parameters_.stroke_x_deg * kDegToRad),
                               focal_px * std::tan(parameters_.stroke_y_deg * kDegToRad));
  // The lens itself stops at the stroke too (the command never asks for more).
  actuator_x_ = LensActuator(parameters_.actuator_natural_hz, parameters_.actuator_damping, step_s,
                             stroke_px_.x());
  actuator_y_ = LensActuator(parameters_.actuator_natural_hz, parameters_.actuator_damping, step_s,
                             stroke_px_.y());
  for (double tau : parameters_.residual_time_constants_s) {
    residual_decay_.push_back(leakDecay(1.0 / tau, step_s));
    residual_weight_.push_back(leakWeight(1.0 / tau, step_s));
  }
  if (!parameters_.nonlinear_features.empty()) {
    excursion_features_ = hasExcursionFeatures(parameters_.nonlinear_features);
    if (excursion_features_) {
      for (double tau : kExcursionIntegralTimeConstantsS) {
        nonlinear_decay_.push_back(leakDecay(1.0 / tau, step_s));
        nonlinear_weight_.push_back(leakWeight(1.0 / tau, step_s));
      }
    }
    if (hasRateBankFeatures(parameters_.nonlinear_features)) {
      for (double tau : kRateBankTimeConstantsS) {
        rate_bank_decay_.push_back(leakDecay(1.0 / tau, step_s));
        rate_bank_weight_.push_back(leakWeight(1.0 / tau, step_s));
      }
    }
    features_ = Eigen::VectorXd::Zero(nonlinearFeatureCount(parameters_.nonlinear_features));
  }
  // Anti-windup needs the angle that gives a limited command: with a gain that is not invertible
  // (no lens motion, gain 0) there is none, and nothing winds up that the lens would show.
  if (parameters_.anti_windup) {
    const double scale = parameters_.gain.cwiseAbs().maxCoeff();
    if (scale > 0.0 && std::abs(parameters_.gain.determinant()) > 1e-6 * scale * scale) {
      anti_windup_ = true;
      inverse_gain_ = parameters_.gain.inverse();
    }
  }
  // A fractional lag: the acted command is interpolated between the two stored around it (so the
  // fit sees a smooth cost in the lag).
  const double lag_steps = parameters_.sensor_lag_s / step_s;
  lag_steps_ = static_cast<std::size_t>(std::floor(lag_steps));
  lag_fraction_ = lag_steps - static_cast<double>(lag_steps_);
  if (parameters_.learned_dynamics.active()) {
    // The network reads the rate at its own step times: a whole number of internal steps.
    const double network_step_s = parameters_.learned_dynamics.network->step_s;
    learned_every_steps_ = std::llround(network_step_s / step_s);
    if (learned_every_steps_ < 1 ||
        std::abs(static_cast<double>(learned_every_steps_) * step_s - network_step_s) > 1e-9)
      throw std::invalid_argument("stabiliser model: the learned dynamics' step (" +
                                  std::to_string(network_step_s) +
                                  " s) must be a whole number of the predictor's steps (" +
                                  std::to_string(step_s) + " s)");
    learned_.emplace(parameters_.learned_dynamics.network, parameters_.learned_dynamics.conditioning);
  }
  reset();
  resets_ = 0;
}

void LensShiftPredictor::reset() {
  started_ = false;
  theta_.setZero();
  smoothed_rate_ = 0.0;
  panning_ = false;
  excursion_sq_ = 0.0;
  residual_state_.assign(parameters_.residual_time_constants_s.size(), Eigen::Vector2d::Zero());
  pending_commands_.assign(lag_steps_ + 1, Eigen::Vector2d::Zero());  // commands of the last steps
  actuator_x_ = LensActuator(parameters_.actuator_natural_hz, parameters_.actuator_damping, step_s_,
                             stroke_px_.x());
  actuator_y_ = LensActuator(parameters_.actuator_natural_hz, parameters_.actuator_damping, step_s_,
                             stroke_px_.y());
  shifts_.clear();
  nonlinear_state_.assign(nonlinear_decay_.size(), Eigen::Vector2d::Zero());
  rate_bank_state_.assign(rate_bank_decay_.size(), Eigen::Vector2d::Zero());
  if (features_.size() > 0) features_.setZero();
  feature_history_.clear();
  if (learned_) learned_->reset();
  learned_last_.setZero();
  learned_before_.setZero();
  if (learned_) {
    const bool skip = parameters_.learned_dynamics.network->w_skip.size() != 0;
    hidden_last_ = hidden_before_ = Eigen::VectorXd::Zero(
        learned_->state().size() + (skip ? learned_->inputs().size() : 0));
  }
  learned_history_.clear();
  ++resets_;
}

bool LensShiftPredictor::addRate(const CameraRateSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.rate_rad_s.allFinite()) return false;
  // A jump back further than a gap (a replayed bag looping, a clock reset): the history no
  // longer leads to this sample, start over from it. A smaller step back is a stray sample.
  if (started_ && sample.stamp_s < last_stamp_s_ - max_gap_s) reset();
  if (started_ && !(sample.stamp_s > last_stamp_s_)) return false;
  if (started_ && sample.stamp_s - last_stamp_s_ > max_gap_s) reset();
  if (!started_) {
    started_ = true;
    last_stamp_s_ = sample.stamp_s;
    last_rate_ = sample.rate_rad_s;
    start_s_ = sample.stamp_s;
    steps_ = 0;
    clock_s_ = sample.stamp_s;
    shifts_.push_back(Eigen::Vector2d::Zero());
    if (record_features_) feature_history_.push_back(features_);
    if (record_learned_ && learned_) learned_history_.push_back(hidden_last_);
    return true;
  }
  // Internal steps up to the new sample, the rate interpolated at each step's middle.
  const double span = sample.stamp_s - last_stamp_s_;
  while (clock_s_ + step_s_ <= sample.stamp_s + 1e-12) {
    const double middle = clock_s_ + 0.5 * step_s_;
    const double alpha = std::clamp((middle - last_stamp_s_) / span, 0.0, 1.0);
    const double end_alpha = std::clamp((clock_s_ + step_s_ - last_stamp_s_) / span, 0.0, 1.0);
    step((1.0 - alpha) * last_rate_ + alpha * sample.rate_rad_s,
         (1.0 - end_alpha) * last_rate_ + end_alpha * sample.rate_rad_s);
  }
  last_stamp_s_ = sample.stamp_s;
  last_rate_ = sample.rate_rad_s;
  return true;
}

void LensShiftPredictor::step(const Eigen::Vector3d& rate_rad_s,
                              const Eigen::Vector3d& end_rate_rad_s) {
  const StabiliserParameters& p = parameters_;
  const Eigen::Vector2d pan_tilt = rate_rad_s.head<2>();
  if (p.pan_detection_rate_rad_s > 0.0) {
    smoothed_rate_ += pan_smoothing_ * (pan_tilt.norm() - smoothed_rate_);
    if (!panning_ && smoothed_rate_ > p.pan_detection_rate_rad_s) panning_ = true;
    if (panning_ && smoothed_rate_ < 0.7 * p.pan_detection_rate_rad_s) panning_ = false;
  }
  if (panning_ || !(p.excursion_centring > 0.0)) {
    theta_ = (panning_ ? decay_pan_ : decay_hold_) * theta_ +
             (panning_ ? weight_pan_ : weight_hold_) * pan_tilt;
  } else {
    // The corner grows with the last command's excursion (at most kMaxExcursion strokes).
    const double corner = 2.0 * kPi * p.highpass_corner_hz *
                          (1.0 + p.excursion_centring * std::min(excursion_sq_, kMaxExcursion * kMaxExcursion));
    theta_ = leakDecay(corner, step_s_) * theta_ + leakWeight(corner, step_s_) * pan_tilt;
  }
  Eigen::Vector2d raw_command =
      focal_px_ * (p.gain * Eigen::Vector2d(std::tan(theta_.x()), std::tan(theta_.y())));
  const Eigen::Vector2d command = limitToStroke(raw_command, stroke_px_, p.circular_stroke, p.soft_stroke);
  if (anti_windup_ && command != raw_command) {
    // Held at the end stop: the angle is the one whose command is the limited one.
    const Eigen::Vector2d tangent = inverse_gain_ * (command / focal_px_);
    theta_ = Eigen::Vector2d(std::atan(tangent.x()), std::atan(tangent.y()));
    raw_command = command;
  }
  excursion_sq_ = (raw_command.cwiseQuotient(stroke_px_)).squaredNorm();
  // Holds lag_steps_ + 2 commands after the push: front = lag_steps_ + 1 steps old.
  pending_commands_.push_back(command);
  const Eigen::Vector2d acted =
      lag_fraction_ * pending_commands_[0] + (1.0 - lag_fraction_) * pending_commands_[1];
  pending_commands_.pop_front();
  Eigen::Vector2d shift(actuator_x_.advance(acted.x()), actuator_y_.advance(acted.y()));
  // The actuator's axes to the image's (after the stroke: a coupled lens can leave the box).
  shift += Eigen::Vector2d(p.actuator_coupling.x() * shift.y(), p.actuator_coupling.y() * shift.x());
  if (!residual_state_.empty()) {
    const std::size_t k_count = residual_state_.size();
    Eigen::VectorXd features(2 * k_count);
    for (std::size_t k = 0; k < k_count; ++k) {
      residual_state_[k] = residual_decay_[k] * residual_state_[k] + residual_weight_[k] * pan_tilt;
      features(static_cast<long>(k)) = residual_state_[k].x();
      features(static_cast<long>(k_count + k)) = residual_state_[k].y();
    }
    shift += focal_px_ * (p.residual * features);
  }
  if (features_.size() > 0) {
    int offset = 0;
    if (excursion_features_) {
      // excursion_v1, per axis i (other axis j), in focal-length units: u the unclipped command,
      // e = u / stroke (bounded), c the clipped command, a the actuator's output. With anti-windup
      // the angle never passes the stroke, so u is the limited command there.
      const Eigen::Vector2d u = raw_command / focal_px_;
      const Eigen::Vector2d limit = stroke_px_ / focal_px_;
      const Eigen::Vector2d c = command / focal_px_;
      const Eigen::Vector2d a =
          Eigen::Vector2d(actuator_x_.positionPx(), actuator_y_.positionPx()) / focal_px_;
      Eigen::Vector2d e;
      for (int i = 0; i < 2; ++i) e(i) = std::clamp(u(i) / limit(i), -kMaxExcursion, kMaxExcursion);
      const Eigen::Vector2d pull = u.cwiseProduct(e.cwiseAbs2());
      for (std::size_t k = 0; k < nonlinear_state_.size(); ++k)
        nonlinear_state_[k] = nonlinear_decay_[k] * nonlinear_state_[k] +
                              nonlinear_weight_[k] / kExcursionIntegralTimeConstantsS[k] * pull;
      for (int i = 0; i < 2; ++i) {
        const int j = 1 - i;
        double* f = features_.data() + i * kExcursionFeaturesPerAxis;
        f[0] = u(i);
        f[1] = limit(i) * std::tanh(e(i));
        f[2] = pull(i);
        f[3] = pull(i) * e(i) * e(i);
        f[4] = c(i);
        f[5] = a(i);
        f[6] = u(i) * e(j) * e(j);
        for (std::size_t k = 0; k < nonlinear_state_.size(); ++k) f[7 + k] = nonlinear_state_[k](i);
      }
      offset = 2 * kExcursionFeaturesPerAxis;
    }
    // rate_bank_v1: the leaky rate integrals (rad), x's then y's.
    for (std::size_t k = 0; k < rate_bank_state_.size(); ++k) {
      rate_bank_state_[k] = rate_bank_decay_[k] * rate_bank_state_[k] + rate_bank_weight_[k] * pan_tilt;
      features_(offset + static_cast<long>(k)) = rate_bank_state_[k].x();
      features_(offset + kRateBankSize + static_cast<long>(k)) = rate_bank_state_[k].y();
    }
    if (p.nonlinear_residual.size() != 0) shift += focal_px_ * (p.nonlinear_residual * features_);
  }
  // From an integer step count: summing step_s_ on epoch-sized stamps would drift (ulp ~ 2e-7 s).
  ++steps_;
  if (learned_) {
    // The network steps at start + n * its step (reading the rate there); in between, its lens is
    // extrapolated from its last two outputs.
    const long long since = steps_ % learned_every_steps_;
    if (since == 0) {
      learned_before_ = learned_last_;
      learned_last_ = p.learned_dynamics.output_map * learned_->step(end_rate_rad_s);
      if (record_learned_) {
        // The state the layer reads: the hidden vector, then the skip path's inputs.
        hidden_before_ = hidden_last_;
        const bool skip = p.learned_dynamics.network->w_skip.size() != 0;
        hidden_last_.resize(learned_->state().size() + (skip ? learned_->inputs().size() : 0));
        hidden_last_.head(learned_->state().size()) = learned_->state();
        if (skip) hidden_last_.tail(learned_->inputs().size()) = learned_->inputs();
      }
    }
    const double fraction = static_cast<double>(since) / static_cast<double>(learned_every_steps_);
    shift += focal_px_ * (learned_last_ + fraction * (learned_last_ - learned_before_));
    if (record_learned_) {
      learned_history_.push_back(hidden_last_ + fraction * (hidden_last_ - hidden_before_));
      while (learned_history_.size() > history_steps_) learned_history_.pop_front();
    }
  }
  clock_s_ = start_s_ + static_cast<double>(steps_) * step_s_;
  shifts_.push_back(shift);
  while (shifts_.size() > history_steps_) shifts_.pop_front();
  if (record_features_) {
    feature_history_.push_back(features_);
    while (feature_history_.size() > history_steps_) feature_history_.pop_front();
  }
}

Eigen::VectorXd LensShiftPredictor::featuresAt(double t_s) const {
  if (feature_history_.empty()) return features_;
  const double last = static_cast<double>(feature_history_.size() - 1);
  return interpolateOnUniformGrid(feature_history_, last - (clock_s_ - t_s) / step_s_);
}

Eigen::VectorXd LensShiftPredictor::learnedStateAt(double t_s) const {
  if (learned_history_.empty()) return hidden_last_;
  const double last = static_cast<double>(learned_history_.size() - 1);
  return interpolateOnUniformGrid(learned_history_, last - (clock_s_ - t_s) / step_s_);
}

bool LensShiftPredictor::covers(double t_s) const {
  if (shifts_.empty()) return false;
  const double oldest = clock_s_ - static_cast<double>(shifts_.size() - 1) * step_s_;
  // Up to the newest sample: after the last whole step (less than one step) the lens is held.
  return t_s >= oldest - 1e-9 && t_s <= last_stamp_s_ + 1e-9;
}

Eigen::Vector2d LensShiftPredictor::lensShiftAt(double t_s) const {
  if (shifts_.empty()) return Eigen::Vector2d::Zero();
  const double last = static_cast<double>(shifts_.size() - 1);
  return interpolateOnUniformGrid(shifts_, last - (clock_s_ - t_s) / step_s_);
}

}  // namespace deep_ois
