// A generic learned model of a stabiliser's lens dynamics: a gated recurrent unit (GRU) over the
// camera's gyro stream, conditioned on a short per-camera vector, that answers the lens shift in
// focal-length units (pixels / focal_px).
//
// Why a recurrent network: an OIS lens position is a causal function of the gyro history, and the
// stabilisers that produce it differ in structure (first or second order centring, Kalman or
// alpha-beta estimators of the intended motion, pan detection, scheduled gains, strokes of any
// shape, anti-windup, actuators, delays, digital loops, a misaligned gyro, Hall nonlinearity).
// Writing one mechanism per design does not converge; one recurrent network pretrained on a wide
// randomised family of designs (core/sim/design_generator.h, by `pretrain_lens_model`) learns
// them all, and a camera picks its own by a few numbers (the conditioning vector), fitted to its
// own lens motions (core/ois/lens_dynamics_adaptation.h).
//
// Inference is here, in Eigen (the torch-free build and the default pipeline run it); training
// is in the net layer (src/net/lens_dynamics_pretraining.cpp). Weights follow torch's GRU layout
// (gates r, z, n stacked in that order), so the trainer copies them verbatim.
//
// The network runs at its own fixed step (step_s): at each step it reads the camera-frame rate
// at the step's time (rad/s, divided by rate_scale_rad_s), leaky integrals of the pan and tilt
// rates (angles, divided by output_scale: what every stabiliser integrates first, so the network
// need not learn to integrate) and the conditioning vector, updates its state and outputs the
// lens (times output_scale, focal-length units): a linear readout of its state plus a linear skip
// path from the rates and integrals (a linear stabiliser is then a readout away). The lens it
// predicts starts centred and at rest with a zero state, as the designs it was trained on do.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace deep_ois {

// A network file that is missing, unreadable or malformed: what() names the file and field.
class LensDynamicsNetworkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// How a network was made: what it was pretrained on and how far. Recorded in its file so a model
// says which designs it has seen (and a design held out of it can be scored apart).
struct LensDynamicsProvenance {
  std::string generator;  // the design generator's version ("design_generator v1")
  std::uint32_t design_seed_begin = 0;  // designs [begin, end) of the generator's training split
  std::uint32_t design_seed_end = 0;
  std::uint32_t designs = 0;            // how many of them (the held-out seeds excluded)
  std::uint32_t motion_seeds_per_design = 0;
  double trace_duration_s = 0.0;
  double focal_px = 0.0;  // the traces' camera (the network's units do not depend on it)
  std::uint64_t iterations = 0;  // optimiser steps done
  double training_loss = 0.0;    // the last iterations' mean loss (output units squared)
  double validation_rms_focal = 0.0;  // lens RMS error on validation designs, focal units
  std::string command;  // the command that made it
};

struct LensDynamicsNetwork {
  static constexpr int kInputRates = 3;  // camera-frame rate x, y, z
  int hidden_size = 0;
  int conditioning_size = 0;
  double step_s = 0.005;
  double rate_scale_rad_s = 1.0;  // input = rate / rate_scale_rad_s
  double output_scale = 0.01;     // lens (focal units) = output * output_scale
  // Time constants of the leaky integrals of the pan and tilt rates fed as inputs (seconds; may be
  // empty): integral s <- d s + tau (1 - d) w per step, d = exp(-step / tau), divided by
  // output_scale. The inputs are x = [rate / rate_scale (3), integrals of x then y (2K)].
  std::vector<double> input_integrals_s;
  int inputSize() const { return kInputRates + 2 * static_cast<int>(input_integrals_s.size()); }
  // GRU weights (torch layout): w_input (3H x (inputs + C)), w_hidden (3H x H), biases 3H each.
  Eigen::MatrixXd w_input, w_hidden;
  Eigen::VectorXd b_input, b_hidden;
  Eigen::MatrixXd w_output;  // 2 x H
  Eigen::Vector2d b_output = Eigen::Vector2d::Zero();
  Eigen::MatrixXd w_skip;    // 2 x inputs (the linear path from the inputs; empty = none)
  // The conditioning vector a camera starts from (the mean of the pretraining designs') and the
  // spread of the designs' vectors per component (the adaptation's prior).
  Eigen::VectorXd default_conditioning, conditioning_spread;
  LensDynamicsProvenance provenance;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;

  std::string toYaml() const;
  // Throws LensDynamicsNetworkError naming the missing or malformed field.
  static LensDynamicsNetwork fromYaml(const std::string& yaml_text);
  static LensDynamicsNetwork load(const std::string& path);  // errors name the file
  void save(const std::string& path) const;                  // atomic (written beside, renamed)
};

// The network a tool's or node's option names: null for "none" or "" (no learned dynamics), else
// the file loaded. Throws LensDynamicsNetworkError naming the file.
std::shared_ptr<const LensDynamicsNetwork> loadLensDynamicsOption(const std::string& path_or_none);

// The network as a YAML map (what toYaml writes, without the document around it): a stabiliser
// model file embeds its network this way.
}  // namespace deep_ois
namespace YAML {
class Emitter;
class Node;
}  // namespace YAML
namespace deep_ois {
void writeLensDynamicsNetwork(YAML::Emitter& out, const LensDynamicsNetwork& network);
// Throws LensDynamicsNetworkError naming the missing or malformed field.
LensDynamicsNetwork readLensDynamicsNetwork(const YAML::Node& node);

// One stream through a network: its state, advanced one network step at a time.
class LensDynamicsRunner {
 public:
  // Throws std::invalid_argument for a null or invalid network or a conditioning vector of the
  // wrong size.
  LensDynamicsRunner(std::shared_ptr<const LensDynamicsNetwork> network,
                     const Eigen::VectorXd& conditioning);
  // Reads the rate at the step's time (camera frame, rad/s); returns the lens after it (focal
  // units).
  Eigen::Vector2d step(const Eigen::Vector3d& rate_rad_s);
  void reset();  // a zero state: centred lens at rest
  const Eigen::VectorXd& state() const { return hidden_; }
  // The inputs of the last step (rates and integrals, scaled; what the skip path reads).
  const Eigen::VectorXd& inputs() const { return inputs_; }

 private:
  std::shared_ptr<const LensDynamicsNetwork> network_;
  Eigen::VectorXd conditioned_bias_;  // b_input + W_input[:, 3:] * conditioning (constant)
  Eigen::VectorXd hidden_;
  Eigen::VectorXd gates_input_, gates_hidden_;  // scratch, 3H
  std::vector<double> integral_decay_, integral_weight_;
  Eigen::VectorXd integrals_;  // 2K: the leaky integrals of x then y (rad)
  Eigen::VectorXd inputs_;
};

}  // namespace deep_ois
