// The learned lens dynamics stage's values (src/core/ois/stages/learned_lens_dynamics_stage.cpp):
// a generic lens dynamics network (core/ois/lens_dynamics_network.h), pretrained on generated
// stabiliser designs, conditioned on this camera's vector. Its lens (focal-length units, through
// output_map) is added to the chain's; a model of it alone has the chain switched off
// (noLensMotion()'s gain 0). It runs at the network's step; between its steps the lens is
// extrapolated from its last two outputs.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "deep_ois/core/ois/lens_dynamics_network.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LearnedLensDynamics : StageValuesOf<LearnedLensDynamics> {
  static constexpr const char* kStage = "learned_lens_dynamics";
  std::shared_ptr<const LensDynamicsNetwork> network;  // null: no learned stage
  Eigen::VectorXd conditioning;                        // network->conditioning_size values
  // Applied to the network's lens (a camera whose lens moves on another scale, or whose axes are
  // turned against the designs'); the identity unless the adaptation fitted it.
  Eigen::Matrix2d output_map = Eigen::Matrix2d::Identity();
  bool active() const { return network != nullptr; }
};

}  // namespace deep_ois
