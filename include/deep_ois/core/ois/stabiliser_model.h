// A learned model of an optical image stabiliser: predicts where the OIS lens is (a shift of the
// principal point, pixels) from the camera's gyro stream, carrying the stabiliser's state across
// frames.
//
// Why a stateful physical model: an OIS lens position is a causal function of the gyro history.
// The stabiliser integrates its gyro, re-centres (a high-pass with its own corner), lets go during
// deliberate pans, saturates at its stroke and moves the lens through an actuator with its own
// bandwidth and a sensor lag. One inter-frame flow cannot carry that state; a model with the same
// structure and a dozen parameters learned per camera can, and it is cheap (microseconds per
// frame). What the structure does not capture is fitted as a linear residual over a bank of
// leaky integrals of the rate (any stable linear dynamics is well approximated by such a bank).
//
// Units are normalised by the focal length where it matters (gain as a fraction of the rotation
// cancelled, stroke in degrees), so a model transfers between cameras of one module that differ
// in resolution. Pure C++/Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_dynamics_network.h"
#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/stabiliser_signal.h"

namespace deep_ois {

// The learned stage: a generic lens dynamics network (core/ois/lens_dynamics_network.h), pretrained
// on generated stabiliser designs, conditioned on this camera's vector. Its lens (focal-length
// units, through output_map) is added to the chain's; a model of it alone has the chain switched
// off (noLensMotion()'s gain 0). It runs at the network's step; between its steps the lens is
// extrapolated from its last two outputs (the predictor answers at any time up to its newest
// gyro sample, as the chain does).
struct LearnedLensDynamics {
  std::shared_ptr<const LensDynamicsNetwork> network;  // null: no learned stage
  Eigen::VectorXd conditioning;                        // network->conditioning_size values
  // Applied to the network's lens (a camera whose lens moves on another scale, or whose axes are
  // turned against the designs'); the identity unless the adaptation fitted it.
  Eigen::Matrix2d output_map = Eigen::Matrix2d::Identity();
  bool active() const { return network != nullptr; }
};

// The linear-dynamics stage's values (src/core/ois/stages/linear_dynamics_stage.cpp): raw command
// += focal_px * coefficients * the state of an orthonormal basis of the three gyro axes
// (core/ois/linear_dynamics_basis.h).
struct LinearDynamicsValues {
  LinearDynamicsBasisSpec basis;
  Eigen::MatrixXd coefficients;  // 2 x 3 basis.order (focal units per basis state); empty = off
  bool active() const { return coefficients.size() != 0; }
};

// The stages of a sampled digital controller, as the simulator's generated designs are built
// (core/sim/stabiliser_design.h says what each mechanism does; its ranges bound them). Each stage
// acts when its values are set. Words as the design names them.
struct GyroLoopValues {  // gyro_loop: the stabiliser's own gyro and when the controller samples it
  double roll_deg = 0.0, tilt_deg = 0.0, pan_deg = 0.0;  // camera -> gyro: roll, then tilt, pan
  double rate_hz = 4000.0;  // controller rate; the step's rate is a multiple of it
  bool averaged = false;    // the mean rate over its period (else the newest sample)
};
struct MotionModeValues {  // motion_mode: pan detection (release, hold) and the gain schedule
  std::string action = "none";  // none, release, hold
  double threshold_rad_s = 0.2, time_constant_s = 0.2, release_factor = 6.0, hold_time_constant_s = 0.1;
  double schedule_depth = 0.0;  // 0 = not scheduled
  double schedule_start_rad_s = 0.1, schedule_span_rad_s = 0.3, schedule_time_constant_s = 0.1;
};
struct IntendedMotionValues {  // intended_motion: the angle to cancel, its gain
  // highpass_first_order, highpass_second_order, velocity_loop, kalman_cv, alpha_beta
  std::string kind = "highpass_first_order";
  double corner_hz = 0.6, damping = 0.8, rate_corner_hz = 0.5;
  double excursion_gain = 0.0, excursion_power = 2.0;  // 0 = a fixed corner
  double gain_x = 1.0, gain_y = 1.0;
};
struct TravelValues {  // travel: the stroke per axis and direction, anti-windup, the DAC
  std::string shape = "box";  // box, ellipse, soft_box, soft_ellipse
  double x_positive_deg = 1.0, x_negative_deg = 1.0, y_positive_deg = 1.0, y_negative_deg = 1.0;
  std::string anti_windup = "none";  // none, clamp, back_calculation
  double back_calculation_rate_per_s = 20.0;
  double quantiser_bits = 0.0;  // 0 = not quantised
};
struct HallActuatorValues {  // hall_actuator: transport delay, the lens' position loop, Hall sensor
  double delay_s = 0.0;
  std::string order = "second";  // first, second
  double bandwidth_hz = 35.0, damping = 0.7, rate_limit_deg_s = 0.0, stiction_fraction = 0.0;
  double end_stop_margin = 1.1, hall_c2 = 0.0, hall_c3 = 0.0;
};

struct StabiliserParameters {
  // Commanded shift = focal_px * gain * (tan theta_x, tan theta_y) for the high-passed pan/tilt
  // angles theta (rad, camera optical frame). An ideal stabiliser of this package's convention has
  // gain = [[0, 1], [-1, 0]] (x follows the turn about y, y against the turn about x); a module
  // cancelling 90 % of the motion has 0.9 of that; a mount turned in the image plane mixes axes.
  Eigen::Matrix2d gain = (Eigen::Matrix2d() << 0.0, 1.0, -1.0, 0.0).finished();
  double highpass_corner_hz = 0.6;  // centring: the integrated angle leaks back with this corner
  double actuator_natural_hz = 35.0;
  double actuator_damping = 0.7;
  double sensor_lag_s = 0.0;  // the position loop acts on commands this old (Hall sensor delay)
  double stroke_x_deg = 1.0;  // commanded shift limits, as angles (f tan(limit) pixels)
  double stroke_y_deg = 1.0;
  bool circular_stroke = false;  // false: a box of the two limits; true: the ellipse inside it
  // A soft stroke: the command u becomes stroke * tanh(u / stroke) (per axis for the box, radially
  // for the ellipse) instead of stopping at the stroke: a lens held by springs whose pull grows
  // towards the end, or a controller that compresses its command as it nears the limit. Exclusive
  // with anti_windup (a soft stroke is never met, so there is no angle to hold).
  bool soft_stroke = false;
  // The integrated angle at the end stop. false: it keeps integrating beyond the stroke (the lens
  // leaves the stroke only once the angle has come back inside); true (anti-windup): it is held
  // where the command meets the stroke, so the lens leaves the stroke as soon as the rate turns.
  // A stabiliser whose lens sits on its stroke much of the time shows which one it has (the
  // Pixel 4's log: anti-windup, docs/stabiliser_model.md).
  bool anti_windup = false;
  // Excursion-dependent re-centring: the centring corner is highpass_corner_hz * (1 + k e^2),
  // e^2 = (u_x / stroke_x)^2 + (u_y / stroke_y)^2 for the command u before the stroke limit
  // (e = 1 on the stroke). k = excursion_centring, 0 = a fixed corner.
  double excursion_centring = 0.0;
  // Cross-coupling after the actuator: the stroke limit and the actuator act in the actuator's own
  // axes (the gain maps the camera's angles into them), and the image shift is
  // (a_x + c_xy a_y, a_y + c_yx a_x) for the actuator's output a and actuator_coupling =
  // (c_xy, c_yx) (a lens whose axes drag each other, a magnet turned against its coil). 0 = none.
  // With the gain it places the stroke's box in the actuator's axes instead of the image's.
  Eigen::Vector2d actuator_coupling = Eigen::Vector2d::Zero();
  // Pan detection: while the low-passed |pan/tilt rate| exceeds the threshold (0 = off) the
  // stabiliser re-centres with pan_release_corner_hz; below 0.7 x the threshold it holds again.
  double pan_detection_rate_rad_s = 0.0;
  double pan_detection_time_constant_s = 0.1;
  double pan_release_corner_hz = 5.0;
  // Linear residual: shift += focal_px * sum_k residual.col(k) ... over the bank of leaky rate
  // integrals with residual_time_constants_s (2 x 2K matrix: the K integrals of rate x then the K
  // of rate y). Empty = none.
  std::vector<double> residual_time_constants_s;
  Eigen::MatrixXd residual;  // 2 x (2 * K), unitless (radians of the leaky integral to focal units)
  // Learned residual (empty name = none): shift += focal_px * nonlinear_residual * features, the
  // features a fixed set of functions of the chain's own state (see nonlinearFeatureCount): the
  // unclipped command, its excursion against the stroke and
  // saturations of it, the clipped command, the actuator's output, and leaky integrals of the
  // excursion-weighted command (what an excursion-dependent re-centring pulls back with). The
  // features depend only on the chain, never on the residual's output, so a ridge regression
  // fits them in one solve. Names the set so a file states which functions its numbers weigh.
  std::string nonlinear_features;
  Eigen::MatrixXd nonlinear_residual;  // 2 x nonlinearFeatureCount(nonlinear_features)
  LearnedLensDynamics learned_dynamics;
  LinearDynamicsValues linear_dynamics;
  std::optional<GyroLoopValues> gyro_loop;
  std::optional<MotionModeValues> motion_mode;
  std::optional<IntendedMotionValues> intended_motion;
  std::optional<TravelValues> travel;
  std::optional<HallActuatorValues> hall_actuator;
  // The model's stages by name, when it is not the default chain ({"linear_dynamics", "stroke",
  // "actuator"}: no centring); only these run (each still only when its values make it act).
  // Empty: every stage whose values make it act (centring, stroke and actuator always), as every
  // file before the key.
  std::vector<std::string> stages;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
  // The chain alone: these parameters without the linear residual bank, the learned residual and
  // the learned dynamics
  // (the "physical" candidate, and the start of a structural refit).
  StabiliserParameters physicalChain() const;
};

// The known feature sets of the learned residual (0 for an unknown name and for ""):
// "excursion_v1" (20: nonlinear functions of the chain's state), "rate_bank_v1" (18: leaky rate
// integrals from 2 ms to 2.5 s, a learned higher-order linear filter) and "excursion_rate_v1"
// (both, 38).
int nonlinearFeatureCount(const std::string& feature_set);

// A camera-frame angular rate sample (IMU clock, seconds; rad/s in the camera optical frame).
struct CameraRateSample {
  double stamp_s = 0.0;
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
};

// Runs the model over a gyro stream and answers the lens shift at any recent time.
class LensShiftPredictor {
 public:
  // Throws std::invalid_argument with the validate() sentence, or for a non-positive focal length
  // or step. `step_s`: the internal integration step (the rate is interpolated linearly between
  // samples); `history_s`: how far back lensShiftAt() can answer.
  LensShiftPredictor(const StabiliserParameters& parameters, double focal_px, double step_s = 1e-3,
                     double history_s = 0.5);

  // Appends a rate sample; samples must come in increasing time. A sample not after the last one
  // is ignored (returns false), unless it is more than max_gap_s before it (time jumped back: the
  // state resets and starts from it). A gap longer than max_gap_s since the previous sample
  // resets the state too (the stabiliser's history is unknown across it): counted in resets().
  bool addRate(const CameraRateSample& sample);
  // Starts over from a centred lens at rest (the state of a stabiliser switched on).
  void reset();

  // The lens shift (pixels, x right, y down) at time t: interpolated between internal steps within
  // the retained history, held after the last step up to the newest sample (less than a step).
  // covers(t) says whether t is inside that span.
  bool covers(double t_s) const;
  Eigen::Vector2d lensShiftAt(double t_s) const;
  double newestStamp() const { return last_stamp_s_; }
  bool started() const { return started_; }
  int resets() const { return resets_; }
  // Keeps the nonlinear features of every retained step (for fitting nonlinear_residual; the
  // model must name a feature set) and answers them like lensShiftAt (focal-length units).
  void recordFeatures() { record_features_ = true; }
  Eigen::VectorXd featuresAt(double t_s) const;
  // Keeps the learned stage's state (the network's hidden vector and, with a skip path, its
  // inputs; extrapolated between its steps as its lens is) of every retained step, and answers it like lensShiftAt: the features a refit
  // of the network's output layer regresses on (core/ois/lens_dynamics_adaptation.h).
  void recordLearnedState() {
    record_learned_ = true;
    chain_.signal().want_learned_state = true;
  }
  Eigen::VectorXd learnedStateAt(double t_s) const;

  double max_gap_s = 0.1;

 private:
  // One internal step: the rate at its middle (the chain) and at its end (a stage that reads the
  // rate at its own step times): the stages' runners in the chain's order.
  void step(const Eigen::Vector3d& rate_rad_s, const Eigen::Vector3d& end_rate_rad_s);

  double step_s_;
  std::size_t history_steps_;
  // The runners of the stages that act for the parameters (core/ois/stabiliser_stage.h).
  StabiliserChain chain_;

  // State.
  bool started_ = false;
  double last_stamp_s_ = 0.0;
  Eigen::Vector3d last_rate_ = Eigen::Vector3d::Zero();
  double start_s_ = 0.0;      // stamp of the first sample since the last reset
  long long steps_ = 0;       // internal steps since then
  double clock_s_ = 0.0;      // time of the newest internal step: start_s_ + steps_ * step_s_
  std::deque<Eigen::Vector2d> shifts_;  // lens shift at clock_s_ - (size - 1 - j) * step_s_
  bool record_features_ = false;
  std::deque<Eigen::VectorXd> feature_history_;  // aligned with shifts_ when recording
  bool record_learned_ = false;
  std::deque<Eigen::VectorXd> learned_history_;  // aligned with shifts_ when recording
  int resets_ = 0;
};

}  // namespace deep_ois
