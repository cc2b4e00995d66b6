// The simulator's stabilisers run over a gyro, from the camera-frame angular velocity to the lens
// shift: a generated design (core/sim/stabiliser_design.h) at kDesignPhysicsRateHz, or a camera
// module's `ois` keys (OisConfig, core/sim/ois_model.h) at ois.control_rate_hz.
//
// Both are stabiliser models (core/ois/stabiliser_model.h) of the stage library's sampled
// controller stages (gyro_loop, motion_mode, intended_motion, travel, hall_actuator, and
// actuator_coupling for a module), and run through the same chain of stage runners as the model's
// predictor: saved as a model file, either predicts its own lens. Two callers: the simulator's
// OisModel runs them on the true motion with the stabiliser's own gyro and Hall noise, and the
// oracle (StabiliserOracle) on a camera's gyro.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <random>

#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/sim/lens_shift_grid.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/stabiliser_design.h"

namespace deep_ois {
namespace sim {

// The design as a model of the stage library, for the predictor's step of 1 / kDesignPhysicsRateHz
// (its lens then equals runDesign's without noise).
StabiliserModel designModel(const StabiliserDesign& design);
// The module as a model of the stage library, for the predictor's step of 1 / control_rate_hz (its
// lens then equals runStabiliser's without noise). Throws std::invalid_argument with the
// validate() sentence, or for pan detection with a release corner below the centring corner (the
// motion_mode stage releases by a factor >= 1).
StabiliserModel moduleModel(const OisConfig& config);

// `design` valid (StabiliserDesign::validate(), else std::invalid_argument naming the field),
// focal_px > 0 (sets pixels per radian), steps >= 1. Physics step j is at
// start_s + j / kDesignPhysicsRateHz; the stabiliser starts centred and at rest at step 0 and the
// result has steps + 1 samples. `angular_velocity_rad_s(t)`: the camera-frame (optical) angular
// velocity, asked once per step j = 0..steps in increasing time; the stabiliser's gyro sees it
// turned by design.mount. `noise`: per step, the Hall reading's white noise (hall.noise_px, drawn
// only when not 0: x, y) and then the stabiliser gyro's (mount.noise_rad_s: x, y in the gyro's
// frame, always drawn); null: none (the oracle).
LensShiftGrid runDesign(const StabiliserDesign& design, double focal_px, double start_s, int steps,
                        const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                        std::mt19937* noise);

// As runDesign for a module: `config` valid (OisConfig::validate()), control step j at
// start_s + j / control_rate_hz; its gyro's noise (ois.gyro_noise_rad_s) is drawn for step 0 too,
// first, as a continuous controller integrates from there.
LensShiftGrid runStabiliser(
    const OisConfig& config, double focal_px, double start_s, int steps,
    const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s, std::mt19937* noise);

}  // namespace sim
}  // namespace deep_ois
