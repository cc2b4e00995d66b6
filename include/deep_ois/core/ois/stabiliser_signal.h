// The signal that flows along the stabiliser model's chain of stages over one internal step, and
// the interface of a stage's runner (its state and its step). The stages themselves are described
// in core/ois/stabiliser_stage.h; the predictor (core/ois/stabiliser_model.h) is a loop over their
// runners. Pure Eigen.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

namespace deep_ois {

// What flows along the chain over one internal step of the predictor. The predictor fills the
// inputs, and each stage's runner reads what the stages before it wrote and writes its own output.
// Pixels are the camera's (the model's focal length); the fields that carry over from one step to
// the next say so.
struct StabiliserSignal {
  // Inputs of the step: the camera-frame rate (rad/s) at the step's middle, and at its end (read by
  // a stage that samples the rate at step times), and the steps since the last reset, this one
  // included.
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d end_rate_rad_s = Eigen::Vector3d::Zero();
  long long step_index = 0;
  // How the integrated angle leaks this step, decided before the centring runs: re-centring with
  // the release decay and weight while a pan is detected (pan detection), else the centring's own
  // corner times corner_scale (excursion re-centring; 1 = the corner itself).
  bool released = false;
  double release_decay = 1.0, release_weight = 0.0;
  double corner_scale = 1.0;
  // The integrated pan/tilt angle (rad; carried over: the stroke's anti-windup holds it at the end
  // stop) and e^2 = |raw command / stroke|^2 of the last step (carried over).
  Eigen::Vector2d angle_rad = Eigen::Vector2d::Zero();
  double excursion_sq = 0.0;
  // The command before the stroke (px), the command the stroke lets through (px), the actuator's
  // output in its own axes (px) and the lens shift in the image (px, what the predictor answers).
  Eigen::Vector2d raw_command_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d command_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d actuator_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d lens_px = Eigen::Vector2d::Zero();
  // What stages add to the lens after the last stage, past the stroke and the actuator (px; a
  // linear-dynamics stage whose output is the lens): zeroed at each step; the chain answers
  // lens_px + lens_added_px.
  Eigen::Vector2d lens_added_px = Eigen::Vector2d::Zero();
  // The stages of a sampled controller (a generated design or a camera module,
  // core/sim/stabiliser_design_runner.h). Inputs a simulator fills: its stabiliser's own sensors'
  // noise over the step (its gyro's at the step's end and, as the mean of the two samples, at its
  // middle, rad/s in the gyro's axes; the Hall reading's, px); zero in a model.
  Eigen::Vector2d gyro_noise_rad_s = Eigen::Vector2d::Zero();
  Eigen::Vector2d gyro_noise_mid_rad_s = Eigen::Vector2d::Zero();
  Eigen::Vector2d hall_noise_px = Eigen::Vector2d::Zero();
  // gyro_loop: whether the controller updates at the end of this step, the pan/tilt rate it
  // samples then and its newest sample (rad/s, its gyro's axes); between updates the command is
  // held.
  bool control_tick = true;
  Eigen::Vector2d sampled_rate_rad_s = Eigen::Vector2d::Zero();
  Eigen::Vector2d newest_rate_rad_s = Eigen::Vector2d::Zero();
  // motion_mode: the gain's multiplier (a hold ramps it to 0, a schedule lowers it with the motion).
  double gain_scale = 1.0;
  // intended_motion -> travel: the command per tan(angle) (px, x and y; angle_rad is the angle
  // cancelled); travel -> intended_motion: how much its anti-windup moves that angle (rad, applied
  // at the next update) and |raw command| / stroke per axis after it (carried over).
  Eigen::Vector2d command_gain_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d angle_correction_rad = Eigen::Vector2d::Zero();
  Eigen::Vector2d excursion = Eigen::Vector2d::Zero();
};

// The constants a runner is built for.
struct StabiliserRunContext {
  double focal_px = 0.0;
  double step_s = 1e-3;  // the predictor's internal step
};

// A stage's state and step. Built by the stage for given parameters (StabiliserStage::runner).
class StabiliserStageRunner {
 public:
  virtual ~StabiliserStageRunner() = default;
  // The state of a stabiliser switched on (a centred lens at rest); sets the runner's carried
  // fields of `signal` to theirs.
  virtual void reset(StabiliserSignal& signal) = 0;
  // One internal step: reads the signal the stages before it wrote, writes its own fields.
  virtual void advance(StabiliserSignal& signal) = 0;
};

// The chain of runners and the signal between them: the one loop every stabiliser runs through, the
// model's predictor (core/ois/stabiliser_model.h) and the simulator's generated designs alike.
class StabiliserChain {
 public:
  StabiliserChain() = default;
  explicit StabiliserChain(std::vector<std::unique_ptr<StabiliserStageRunner>> runners)
      : runners_(std::move(runners)) {}

  // A stabiliser switched on.
  void reset() {
    signal_ = StabiliserSignal();
    for (const auto& runner : runners_) runner->reset(signal_);
  }
  // One internal step from the rate at its middle and at its end (rad/s, camera frame); set the
  // simulator's noise inputs in signal() before. Returns the lens (px).
  Eigen::Vector2d step(const Eigen::Vector3d& rate_rad_s, const Eigen::Vector3d& end_rate_rad_s) {
    signal_.rate_rad_s = rate_rad_s;
    signal_.end_rate_rad_s = end_rate_rad_s;
    ++signal_.step_index;
    // The stages that write the raw command set it (centring) or add to it (linear dynamics).
    signal_.raw_command_px.setZero();
    signal_.lens_added_px.setZero();
    for (const auto& runner : runners_) runner->advance(signal_);
    return signal_.lens_px + signal_.lens_added_px;
  }
  StabiliserSignal& signal() { return signal_; }
  const StabiliserSignal& signal() const { return signal_; }

 private:
  std::vector<std::unique_ptr<StabiliserStageRunner>> runners_;
  StabiliserSignal signal_;
};

}  // namespace deep_ois
