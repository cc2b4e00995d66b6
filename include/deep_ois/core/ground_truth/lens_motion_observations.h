// The lens motions a gyro-anchored lens trajectory (lens_shift_ground_truth.h) measured: per frame
// pair and row patch, s_b - s_a at the patches' IMU capture times, for the pairs with enough inlier
// tracks. What the stabiliser fit (core/ois/stabiliser_fit.h) learns from. One path for
// train_stabiliser's images target and the live pipeline's online learner
// (core/online/online_stabiliser_learner.h).
#pragma once

#include <cstddef>
#include <vector>

#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

// Fewer inlier tracks than this in a pair: its lens motion is left out (the prior filled it in).
constexpr int kMinimumLensMotionInlierTracks = 8;

struct TrajectoryLensMotions {
  std::vector<LensMotionObservation> observations;  // patch_count per pair used, pair order
  std::size_t pairs_without_tracks = 0;             // pairs left out: too few inlier tracks
  std::vector<double> median_track_residual_px;     // of each pair used
};

// `pairs` and `trajectory` as given to and returned by estimateLensShiftTrajectory;
// `frame_stamps_s` the frames' stamps (camera clock; `timing` turns them into IMU patch times).
TrajectoryLensMotions lensMotionsOfTrajectory(const std::vector<LensShiftPairObservation>& pairs,
                                              const LensShiftTrajectory& trajectory,
                                              const std::vector<double>& frame_stamps_s,
                                              const RollingShutterConfig& timing,
                                              int minimum_inlier_tracks = kMinimumLensMotionInlierTracks);

}  // namespace deep_ois
