// Exact ground truth of a simulated frame pair: the true per-patch motion with and without the
// OIS lens shift, and annotated point correspondences on the static background.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "deep_ois/core/sim/scene.h"
#include "deep_ois/core/sim/sim_camera.h"
#include "deep_ois/core/sim/simulator_config.h"

namespace deep_ois {
namespace sim {

struct FramePairTruth {
  double stamp_a_s = 0.0;  // camera clock (simulation seconds), frame a = the earlier frame
  double stamp_b_s = 0.0;
  // Per row patch i, at the times the gyro flow uses (patch_time centre, time_offset 0):
  // t_a(i) = stamp_a + readout * (i + 0.5) / N, t_b(i) = t_a(i) + (stamp_b - stamp_a).
  std::vector<double> patch_times_a_s;
  std::vector<Eigen::Matrix3d> rotations_b_a;  // camera frame a -> camera frame b (true)
  // K R_b_a K^-1: the motion a perfect gyro predicts (what a non-OIS camera shows, parallax aside).
  std::vector<Eigen::Matrix3d> homographies_without_ois;
  // K(t_b) R_b_a K(t_a)^-1 with the lens-shifted intrinsics: the rotation-induced motion the OIS
  // camera really shows.
  std::vector<Eigen::Matrix3d> homographies_with_ois;
  std::vector<Eigen::Vector2d> lens_shift_a_px;  // OIS shift at t_a(i), pixels
  std::vector<Eigen::Vector2d> lens_shift_b_px;  // OIS shift at t_b(i), pixels
  // Annotated correspondences: the same static 3D point in frame a and frame b, raw pixels,
  // each at the time its own row is exposed (rolling shutter, OIS and parallax included).
  std::vector<Eigen::Vector2d> points_a_px;
  std::vector<Eigen::Vector2d> points_b_px;
};

// Computes the truth of the pair (stamp_a_s, stamp_b_s). Correspondences: between
// min_correspondences and max_correspondences points (count and positions drawn from `seed`),
// one per cell of a grid over the image, on static planes visible in both frames (not occluded,
// not on the moving object), at least `margin_px` inside both images.
FramePairTruth computeFramePairTruth(const SimCamera& camera, const Scene& scene, double stamp_a_s,
                                     double stamp_b_s, const GroundTruthConfig& config,
                                     std::uint32_t seed, double margin_px = 8.0);

}  // namespace sim
}  // namespace deep_ois
