// Adapting the generic lens dynamics network (core/ois/lens_dynamics_network.h) to one camera:
// only what the camera's data supports is fitted: its conditioning vector (a few numbers, started
// at the pretraining designs' mean and pulled towards their distribution), and optionally a 2x2
// map of the network's lens (scale and axes). The network's weights stay as pretrained.
//
// The data is what the chain's fit uses (core/ois/stabiliser_fit.h): lens motions between the
// frames of each recording, from the images (gyro-anchored), a lens log or the simulator's truth.
// The solver: the package's (core/common/nonlinear_least_squares.h), Huber loss per observation,
// derivatives by forward differences over the conditioning (one pass over the gyro per component)
// and in closed form over the map (the lens is linear in it). Pure C++: no ROS, no torch.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_dynamics_network.h"
#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

struct LensDynamicsAdaptationOptions {
  bool fit_output_map = false;
  int iterations = 12;  // solver iterations
  // The pull of the conditioning towards the pretraining designs' distribution: the cost adds
  // prior_weight_px2 * sum(((c - mean) / spread)^2) to the sum of Huber costs (pixels^2).
  double prior_weight_px2 = 1.0;
  // Forward-difference step of each conditioning component, in its spread.
  double difference_step = 1e-3;
};

struct LensDynamicsAdaptation {
  StabiliserModel parameters;  // noLensMotion()'s chain with the adapted learned stage
  std::size_t observations_used = 0;
  double rms_start_px = 0.0;  // lens-motion RMS with the network's default conditioning
  double rms_px = 0.0;        // after the adaptation
  std::vector<double> rms_history;  // after each accepted step
  int passes = 0;                   // passes over the gyro streams (the cost)
};

// Throws std::invalid_argument for a null or invalid network, or when no observation is usable.
LensDynamicsAdaptation adaptLensDynamics(std::shared_ptr<const LensDynamicsNetwork> network,
                                         const std::vector<StabiliserFitRecording>& recordings,
                                         const StabiliserFitOptions& fit_options,
                                         const LensDynamicsAdaptationOptions& options = {});

// The network's output layer refitted to the camera: `adapted` (an adaptLensDynamics result, or any
// model with a learned stage) with the linear map from the network's state to the lens fitted by
// ridge regression (weight `ridge` relative to each state component's energy, pulled towards the
// adapted layer; Huber weights as fit_options.huber_px) on the lens motion the rest of the model
// leaves. The network's recurrent weights stay; the refitted layer is stored in the model's copy of
// the network (output_map folded in). Throws std::invalid_argument as adaptLensDynamics.
StabiliserModel refitLensDynamicsOutput(const StabiliserModel& adapted,
                                             const std::vector<StabiliserFitRecording>& recordings,
                                             const StabiliserFitOptions& fit_options,
                                             double ridge = 1e-2);

// The stabiliser model of the network with its default conditioning (what a camera starts from
// before any adaptation): noLensMotion()'s chain off, the learned stage on.
StabiliserModel genericLensDynamicsModel(std::shared_ptr<const LensDynamicsNetwork> network);

}  // namespace deep_ois
