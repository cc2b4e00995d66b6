// A generated design's trace as the per-camera fit sees a camera (core/ois/stabiliser_fit.h): the
// camera's gyro and the lens motion of every frame pair and row patch from 1 s on (when a model's
// warm-up is over), with the images' measurement noise. One definition for the benchmarks that
// score lens models on generated designs (benchmark_lens_dynamics, benchmark_linear_dynamics), so
// their figures are comparable.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/sim/design_traces.h"

namespace deep_ois {

// The camera the traces are seen through (the standard split's RE camera by default).
struct DesignTraceCamera {
  double focal_px = 257.0;
  double frame_rate_hz = 30.0;
  double readout_s = 0.022;
  int patches = 8;
};

// The lens (pixels) at time t, linear between the gyro samples it is given at; held before the
// first and after the last.
Eigen::Vector2d lensAtGyroTime(const std::vector<CameraRateSample>& gyro,
                               const std::vector<Eigen::Vector2d>& lens, double t_s);

// `lens`: one value per gyro sample of `trace`. `noise_px`: the standard deviation per axis of the
// noise added to each lens motion (0: none), drawn from `noise_seed`.
StabiliserFitRecording designTraceRecording(const sim::DesignTrace& trace,
                                            const std::vector<Eigen::Vector2d>& lens,
                                            const DesignTraceCamera& camera, double noise_px,
                                            std::uint32_t noise_seed);

}  // namespace deep_ois
