// The simulator's stabiliser run over a gyro: the controller (stabiliser_controller.h), its
// digital timing, the Hall sensor, the lens position loop and the mount, from the camera-frame
// angular velocity to the lens shift at ois.control_rate_hz.
//
// Two callers, one code path: the simulator's OisModel runs it on the true motion with the
// stabiliser's own gyro noise and Hall noise; the oracle (stabiliser_oracle.h) runs the same
// design on a camera's recorded gyro, to say what the best model of that design could do with the
// camera's IMU.
//
// Not yet built from the stabiliser stage library, as the generated designs are (runDesign,
// stabiliser_design_runner.h): the modules' controller (a high-pass on the step's mean rate with pan
// detection on the rate's norm, a Kalman filter with a manoeuvre gate, excursion re-centring on the
// angle), their quantiser in degrees and the PI position loop have no stage of the same behaviour.
// test_sim's StabiliserLensGolden.CommittedModules pins this chain's lens for when they move.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <random>

#include "deep_ois/core/sim/lens_shift_grid.h"
#include "deep_ois/core/sim/ois_model.h"

namespace deep_ois {
namespace sim {

// `config` valid (OisConfig::validate()), focal_px > 0, steps >= 1. Control step j is at
// start_s + j / control_rate_hz; the stabiliser starts centred and at rest at step 0 and the
// result has steps + 1 samples. `angular_velocity_rad_s(t)`: the camera-frame (optical) angular
// velocity at t, asked once per step in increasing time; the stabiliser's gyro sees it turned by
// ois.mount_rotation_deg. `noise`: the stabiliser's own sensors' noise drawn from it in the
// simulator's order (per step its gyro's white noise, ois.gyro_noise_rad_s, and the Hall sensor's,
// ois.hall_noise_px, when not 0); null: no noise (a gyro that brings its own, and the Hall
// sensor's mean, zero).
LensShiftGrid runStabiliser(const OisConfig& config, double focal_px, double start_s, int steps,
                            const std::function<Eigen::Vector3d(double t_s)>& angular_velocity_rad_s,
                            std::mt19937* noise);

}  // namespace sim
}  // namespace deep_ois
