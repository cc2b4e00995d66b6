// Lens-level data of generated stabiliser designs (core/sim/design_generator.h), without rendering
// an image: the designs run over gyro traces, lens shift (pixels) per time, for the benchmarks that
// fit and score lens models on them (benchmark_lens_dynamics, benchmark_linear_dynamics).
//
// Two entry points:
//  - designLensShifts: a design over a gyro trace you have (timestamps and the camera-frame rate):
//    the lens its own controller would command from that gyro (the design's oracle);
//  - simulateDesignTrace: a (design seed, motion seed) pair drawn whole: the simulator's hand-held
//    motion, the camera's gyro sampled from it (with the camera IMU's noise and bias, as a model
//    sees it at run time) and the design's true lens (run on its own noisy gyro, as in a bag),
//    both from t = 0, where the stabiliser starts centred and at rest.
//    Cost: about the length of the trace x 4 kHz physics steps (well under a second per 10 s).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"  // CameraRateSample
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/imu_model.h"

namespace deep_ois {
namespace sim {

// The lens shift (pixels, x right, y down) of `design` at each sample's stamp, its controller
// driven by `gyro` (camera optical frame, rad/s; linear between samples) from start_s (NaN: the
// first sample), centred and at rest then. focal_px: the camera's focal length in pixels. A sample
// not later than the one before does not drive the design (StabiliserOracle drops it); its entry
// is still the lens at its stamp (one entry per input sample). Throws std::invalid_argument as
// StabiliserOracle does.
std::vector<Eigen::Vector2d> designLensShifts(
    const StabiliserDesign& design, double focal_px, const std::vector<CameraRateSample>& gyro,
    double start_s = std::numeric_limits<double>::quiet_NaN());

struct DesignTraceOptions {
  double duration_s = 10.0;  // from t = 0, the first gyro sample, where the stabiliser starts at rest
  double focal_px = 257.0;   // the RE camera: 360 px over 70 degrees
  CameraMotionConfig motion;  // hand-held shake and pans (config/simulator/RE.yaml's)
  // The camera's gyro: rate, noise, bias; its imu_to_camera_rotation is undone (the trace is in
  // the camera frame); time_offset_s must be 0 (one clock).
  ImuConfig imu;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

struct DesignTrace {
  std::uint32_t design_seed = 0;
  std::uint32_t motion_seed = 0;
  std::string design_class;  // designClass()
  DesignSplit split = DesignSplit::kTraining;
  std::vector<CameraRateSample> gyro;  // the camera's gyro, camera frame, stamps from 0 (seconds)
  std::vector<Eigen::Vector2d> lens_px;  // the design's true lens at each gyro stamp
};

// Throws std::invalid_argument naming the bad option. Deterministic per (design_seed, motion_seed,
// options).
DesignTrace simulateDesignTrace(std::uint32_t design_seed, std::uint32_t motion_seed,
                                const DesignTraceOptions& options = DesignTraceOptions());

}  // namespace sim
}  // namespace deep_ois
