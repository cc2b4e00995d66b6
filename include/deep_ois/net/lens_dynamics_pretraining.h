// Pretraining the generic lens dynamics network (core/ois/lens_dynamics_network.h) on the design
// generator's stabilisers (core/sim/design_generator.h): each design of the training split run
// over simulated hand-held gyro traces, the network and one conditioning vector per design
// learned together (the vectors are the designs' "codes"; a new camera later fits only its own,
// core/ois/lens_dynamics_adaptation.h).
//
// Long (hours for a shipped model) but done once and reproducible: deterministic per options, a
// checkpoint written every few hundred iterations, and a run resumed from it continues where it
// stopped. The header is torch-free; the training is in src/net/lens_dynamics_pretraining.cpp.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_dynamics_network.h"

namespace deep_ois {

struct LensDynamicsPretrainingOptions {
  // Designs of the generator's training split in [design_seed_begin, design_seed_end) (the
  // held-out seeds, seed % 5 == 0, are never used); the last `validation_designs` of them are not
  // trained on and score the network as it goes.
  std::uint32_t design_seed_begin = 1;
  std::uint32_t design_seed_end = 1001;
  std::uint32_t validation_designs = 40;
  std::uint32_t motion_seeds_per_design = 3;
  double trace_duration_s = 6.0;
  // The motion of each trace: the RE camera's hand-held shake and pans, scaled by a factor drawn
  // log-uniformly in [1 / motion_spread, motion_spread] (shake and pans apart), so that the
  // network sees the amplitudes of other cameras and hands.
  double motion_spread = 2.0;
  // Leaky integrals of the pan and tilt rates fed to the network beside the rates (seconds; empty:
  // the rates alone, the shipped network), and a linear skip path from them to the lens
  // (core/ois/lens_dynamics_network.h). With {0.05, 0.15, 0.4, 1, 2.5} the training loss fell
  // faster but the validation designs scored lower (docs/results/stabiliser_model.md).
  std::vector<double> input_integrals_s;
  int hidden_size = 64;
  int conditioning_size = 8;
  double step_s = 0.005;
  int batch_size = 32;
  std::uint64_t iterations = 6000;
  double learning_rate = 3e-3;        // Adam; cosine decay to final_learning_rate
  double final_learning_rate = 2e-4;
  // Lens motion over motion_lag_s is weighted beside the lens position: it is what the images
  // measure (the motion between two frames), so the network must get it right, not only the
  // position.
  double motion_lag_s = 0.035;
  double motion_loss_weight = 2.0;
  double conditioning_penalty = 1e-3;  // on the designs' vectors (keeps them near 0, the prior)
  unsigned seed = 1;
  int threads = 1;  // torch's intra-op threads
  std::string checkpoint_path;  // written every checkpoint_every iterations and at the end
  std::uint64_t checkpoint_every = 200;
  // Written at every checkpoint too when non-empty (the network as it stands, usable at once).
  std::string network_path;
  bool resume = true;           // continue from checkpoint_path when it exists and matches
  std::string command;          // recorded in the network's provenance
  const std::atomic<bool>* stop_requested = nullptr;  // polled between iterations

  std::string validate() const;  // empty, or a sentence naming the bad option
  // The options that decide the result (a checkpoint of other options is not resumed).
  std::string signature() const;
};

struct LensDynamicsPretrainingProgress {
  std::string stage;  // "traces" or "training"
  std::uint64_t done = 0;
  std::uint64_t total = 0;
  double loss = 0.0;              // training: mean loss of the last iterations
  double validation_rms_focal = 0.0;  // training: at the last checkpoint (0 before the first)
};

// Throws std::invalid_argument for invalid options, std::runtime_error for a checkpoint that
// cannot be read or written (naming the file). With stop_requested set it checkpoints and returns
// the network as it stands.
LensDynamicsNetwork pretrainLensDynamics(
    const LensDynamicsPretrainingOptions& options,
    const std::function<void(const LensDynamicsPretrainingProgress&)>& progress = {});

}  // namespace deep_ois
