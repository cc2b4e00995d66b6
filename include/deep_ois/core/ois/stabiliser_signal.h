// The signal that flows along the stabiliser model's chain of stages over one internal step, and
// the interface of a stage's runner (its state and its step). The stages themselves are described
// in core/ois/stabiliser_stage.h; the predictor (core/ois/stabiliser_model.h) is a loop over their
// runners. Pure Eigen.
#pragma once

#include <Eigen/Core>

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
  // The learned residual's features (focal units; sized by its runner's reset) and the learned
  // dynamics' state (filled only when want_learned_state), for refits of those stages.
  Eigen::VectorXd features;
  bool want_learned_state = false;
  Eigen::VectorXd learned_state;
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

}  // namespace deep_ois
