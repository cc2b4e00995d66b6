// A stabiliser design as data: a chain of stages, each with its own parameters and ranges, from
// the stabiliser's gyro to the lens. The design generator (core/sim/design_generator.h) draws one
// per seed; core/sim/stabiliser_design_runner.h runs it (in the simulator on the true motion, in
// its oracle on a camera's gyro).
//
// Why a second description beside OisConfig: OisConfig is the simulator's hand-named modules, one
// key per mechanism. The generated family composes the same kinds of mechanism freely (and more of
// them: second-order centring, alpha-beta estimators, velocity-domain loops, mode detection that
// lets go or holds, gain schedules, asymmetric strokes, anti-windup variants, first-order and
// stiction-bound actuators, Hall nonlinearity, a gyro misaligned about all three axes), so that a
// learned lens model is measured on stabilisers no hand-written chain lists.
//
// The chain, in the order a control step runs it:
//   mount (gyro misalignment, noise) -> loop (rate, sampling) -> estimator (centring / intended
//   motion, of a class) -> centring modifiers (excursion) -> mode detection (pan) -> gain (static,
//   scheduled by the motion) -> stroke -> anti-windup -> quantiser -> transport delay ->
//   actuator (order, slew limit, stiction, end stop) -> Hall sensor (nonlinearity, noise) -> lens.
// Angles in degrees and rates in Hz in the design; pixels only once a focal length is given.
// It runs as a model of the stabiliser stage library (designModel, stabiliser_design_runner.h):
// these structs are what the generator draws and validates, the stages' values what runs.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace deep_ois {
namespace sim {

// The stabiliser's own gyro and how it sits against the camera.
struct GyroMountStage {
  // Rotation from the camera frame to the stabiliser gyro's: about the optical axis (roll), then
  // camera x and y, degrees. A misaligned gyro sees part of the camera's roll as pan and tilt.
  double roll_deg = 0.0;
  double tilt_deg = 0.0;
  double pan_deg = 0.0;
  double noise_rad_s = 0.002;  // white noise per physics step (simulator only; the oracle has none)
  Eigen::Matrix3d cameraToGyro() const;
};

// When the controller runs. At kDesignPhysicsRateHz it is continuous; slower, it samples its gyro,
// updates its command once per period and holds it (zero-order hold).
enum class GyroSampling {
  kLatest,    // the newest sample (no anti-aliasing)
  kAveraged,  // the mean over the period (a decimation filter)
};
struct LoopStage {
  double rate_hz = 4000.0;  // a divisor of kDesignPhysicsRateHz
  GyroSampling sampling = GyroSampling::kLatest;
};

// What the lens is asked to cancel: the stabiliser's angle minus what it takes to be intended.
// The class of a design is the class of its estimator (designClass()).
enum class EstimatorKind {
  kHighpass1,     // first-order centring: a leaky integrator of the rate, corner_hz
  kHighpass2,     // second-order centring: the angle minus a 2nd-order low-pass of it (corner_hz,
                  // damping)
  kVelocityLoop,  // velocity domain: the rate high-passed first (rate_corner_hz), then a leaky
                  // integral (corner_hz)
  kKalman,        // intended motion: constant-velocity Kalman filter of bandwidth corner_hz
  kAlphaBeta,     // intended motion: alpha-beta filter of bandwidth corner_hz, damping
};
struct EstimatorStage {
  EstimatorKind kind = EstimatorKind::kHighpass1;
  double corner_hz = 0.6;
  double damping = 0.8;         // kHighpass2, kAlphaBeta
  double rate_corner_hz = 0.5;  // kVelocityLoop
  // Excursion-dependent centring (0 = fixed): the corner (the Kalman filter's bandwidth) times
  // 1 + excursion_gain (|excursion| / stroke)^excursion_power, per axis.
  double excursion_gain = 0.0;
  double excursion_power = 2.0;
};

// Pan (mode) detection on the sustained pan/tilt rate (the norm of the rate vector's low-pass, in
// which the shake averages out), with hysteresis (on above the threshold, off below 0.7 x it).
enum class ModeAction {
  kNone,
  kRelease,  // re-centre faster: the corner (bandwidth) times release_factor while panning
  kHold,     // stop compensating: the gain falls to 0 (and back) with hold_time_constant_s
};
struct ModeStage {
  ModeAction action = ModeAction::kNone;
  double threshold_rad_s = 0.2;
  double time_constant_s = 0.2;  // low-pass of the rate vector it decides on
  double release_factor = 6.0;
  double hold_time_constant_s = 0.1;
};

// Gain: per lens axis, times a schedule that lowers it with the (low-passed) motion: from 1 at
// schedule_start_rad_s to 1 - schedule_depth at schedule_start_rad_s + schedule_span_rad_s.
struct GainStage {
  double gain_x = 1.0;
  double gain_y = 1.0;
  double schedule_depth = 0.0;  // 0 = not scheduled
  double schedule_start_rad_s = 0.1;
  double schedule_span_rad_s = 0.3;
  double schedule_time_constant_s = 0.1;
};

// The travel the command is limited to, per axis and direction (asymmetric when they differ).
enum class StrokeKind {
  kBox,          // clipped per axis
  kEllipse,      // clipped radially (half-axes per quadrant)
  kSoftBox,      // limit tanh(command / limit) per axis
  kSoftEllipse,  // radially, the same
};
struct StrokeStage {
  StrokeKind kind = StrokeKind::kBox;
  double x_positive_deg = 1.0;
  double x_negative_deg = 1.0;
  double y_positive_deg = 1.0;
  double y_negative_deg = 1.0;
  bool asymmetric() const;
};

// What happens to the estimator's state while the command is beyond the (hard) stroke.
enum class AntiWindupKind {
  kNone,             // it winds up: the lens stays at the stop until the angle comes back
  kClamp,            // the cancelled angle is held at the stroke (conditional integration)
  kBackCalculation,  // it is pulled back to the stroke at back_calculation_rate_per_s
};
struct AntiWindupStage {
  AntiWindupKind kind = AntiWindupKind::kNone;
  double back_calculation_rate_per_s = 20.0;
};

// A DAC: the command quantised to (x_positive + x_negative) stroke / 2^bits (0 = not quantised),
// then late by delay_s (transport delay: bus, driver IC), rounded to physics steps.
struct OutputStage {
  int quantiser_bits = 0;
  double delay_s = 0.0;
};

// The lens under its Hall-sensor position loop, from the command to the Hall reading.
enum class ActuatorOrder { kFirst, kSecond };
struct ActuatorStage {
  ActuatorOrder order = ActuatorOrder::kSecond;
  double bandwidth_hz = 35.0;  // first order: corner; second order: natural frequency
  double damping = 0.7;        // second order
  double rate_limit_deg_s = 0.0;  // slew limit of the lens (0 = none)
  // Stiction (0 = none): the lens sticks while the loop's error is below this fraction of the
  // x stroke, and slides against half of it once moving.
  double stiction_fraction = 0.0;
  double end_stop_margin = 1.1;  // the mechanical end stop, times the stroke
};

// The Hall sensor: the loop drives its reading h(x) to the command, so the lens sits at h^-1;
// h(x) = x + c2 L (x/L)^2 + c3 L (x/L)^3 per axis (L that axis' largest stroke).
struct HallStage {
  double c2 = 0.0;
  double c3 = 0.0;
  double noise_px = 0.0;  // white noise of the reading (simulator only; the oracle has its mean)
};

struct StabiliserDesign {
  std::uint32_t seed = 0;  // the generator's seed it came from (0 for a hand-built design)
  GyroMountStage mount;
  LoopStage loop;
  EstimatorStage estimator;
  ModeStage mode;
  GainStage gain;
  StrokeStage stroke;
  AntiWindupStage anti_windup;
  OutputStage output;
  ActuatorStage actuator;
  HallStage hall;

  // Empty, or "stage.field: problem" for the first value outside designParameterRanges() (or an
  // inconsistent structure, e.g. a loop rate that does not divide the physics rate).
  std::string validate() const;
};

// Every design runs its physics (actuator, delay, Hall) at this rate, seconds in between.
constexpr double kDesignPhysicsRateHz = 4000.0;

// A parameter's stated range (inclusive), used to draw it, to validate it and to document it.
struct DesignParameterRange {
  const char* name;  // "stage.field"
  double min, max;
  const char* unit;
  const char* what;
};
const std::vector<DesignParameterRange>& designParameterRanges();
// The range called `name`; throws std::out_of_range for an unknown name.
const DesignParameterRange& designParameterRange(const std::string& name);
// The design's parameters that are in use (a stage that is off states none), by range name.
std::vector<std::pair<std::string, double>> designParameters(const StabiliserDesign& design);

// The design's class, for per-class reporting: its estimator's ("highpass_first_order",
// "highpass_second_order", "velocity_loop", "kalman_cv", "alpha_beta").
const char* designClass(const StabiliserDesign& design);
const std::vector<std::string>& designClasses();
// The structural choices of every stage, as tags (e.g. "centring_excursion", "mode_release",
// "stroke_soft", "actuator_stiction"): designFeatureTags() lists all there are.
std::vector<std::string> designFeatures(const StabiliserDesign& design);
const std::vector<std::string>& designFeatureTags();
// One line per stage, for logs, CSV comments and plots.
std::string describe(const StabiliserDesign& design);

const char* toString(EstimatorKind kind);
const char* toString(StrokeKind kind);
const char* toString(AntiWindupKind kind);
const char* toString(ModeAction action);

}  // namespace sim
}  // namespace deep_ois
