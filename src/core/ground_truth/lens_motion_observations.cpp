#include "deep_ois/core/ground_truth/lens_motion_observations.h"

namespace deep_ois {

TrajectoryLensMotions lensMotionsOfTrajectory(const std::vector<LensShiftPairObservation>& pairs,
                                              const LensShiftTrajectory& trajectory,
                                              const std::vector<double>& frame_stamps_s,
                                              const RollingShutterConfig& timing,
                                              int minimum_inlier_tracks) {
  TrajectoryLensMotions out;
  if (trajectory.shift_px.empty()) return out;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    if (trajectory.pair_inliers[p] < minimum_inlier_tracks) {
      ++out.pairs_without_tracks;
      continue;
    }
    out.median_track_residual_px.push_back(trajectory.pair_median_residual_px[p]);
    const auto a = static_cast<std::size_t>(pairs[p].frame_a);
    const auto b = static_cast<std::size_t>(pairs[p].frame_b);
    for (int i = 0; i < timing.patch_count; ++i) {
      LensMotionObservation o;
      o.t_a_s = patchImuTime(timing, frame_stamps_s[a], i);
      o.t_b_s = patchImuTime(timing, frame_stamps_s[b], i);
      const auto patch = static_cast<std::size_t>(i);
      o.motion_px = trajectory.shift_px[b][patch] - trajectory.shift_px[a][patch];
      out.observations.push_back(o);
    }
  }
  return out;
}

}  // namespace deep_ois
