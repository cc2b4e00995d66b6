#include "deep_ois/core/sim/ground_truth.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <random>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {
namespace sim {

namespace {

// Whether the static point X is what the camera sees at pixel `pixel` of a frame at time t: the
// first surface along the ray must be X's own plane at X's distance.
bool visibleAt(const SimCamera& camera, const Scene& scene, const Eigen::Vector3d& X, int plane,
               double t_s) {
  const Eigen::Vector3d centre = camera.motion().pose(t_s).centre_world_m;
  const Eigen::Vector3d direction = (X - centre).normalized();
  SceneHit hit;
  if (!scene.intersect(centre, direction, t_s, &hit)) return false;
  return hit.plane_index == plane && std::abs(hit.distance_m - (X - centre).norm()) < 1e-6 * (1.0 + hit.distance_m);
}

}  // namespace

FramePairTruth computeFramePairTruth(const SimCamera& camera, const Scene& scene, double stamp_a_s,
                                     double stamp_b_s, const GroundTruthConfig& config,
                                     std::uint32_t seed, double margin_px) {
  FramePairTruth truth;
  truth.stamp_a_s = stamp_a_s;
  truth.stamp_b_s = stamp_b_s;
  const SensorConfig& sensor = camera.sensor();
  const Eigen::Matrix3d& K = camera.nominal().K();
  const int patches = config.patch_count;
  for (int i = 0; i < patches; ++i) {
    const double t_a = stamp_a_s + sensor.readout_time_s * (i + 0.5) / patches;
    const double t_b = t_a + (stamp_b_s - stamp_a_s);
    const Eigen::Matrix3d R_b_a = camera.motion().pose(t_b).R_world_cam.transpose() *
                                  camera.motion().pose(t_a).R_world_cam;
    truth.patch_times_a_s.push_back(t_a);
    truth.rotations_b_a.push_back(R_b_a);
    truth.homographies_without_ois.push_back(rotationHomography(K, R_b_a));
    Eigen::Matrix3d H = camera.intrinsicsAt(t_b) * R_b_a * camera.intrinsicsAt(t_a).inverse();
    truth.homographies_with_ois.push_back(H / H(2, 2));
    truth.lens_shift_a_px.push_back(camera.ois().lensShift(t_a));
    truth.lens_shift_b_px.push_back(camera.ois().lensShift(t_b));
  }

  // One point per grid cell; cells are picked in a seeded order so that 6-8 points spread out.
  std::mt19937 rng(seed);
  const int count = config.min_correspondences +
                    static_cast<int>(uniform01(rng) * (config.max_correspondences - config.min_correspondences + 1));
  const int cols = 4, rows = 2 + (count > 8 ? 1 : 0);
  std::vector<int> cells(cols * rows);
  for (int c = 0; c < cols * rows; ++c) cells[c] = c;
  for (int c = cols * rows - 1; c > 0; --c) {
    std::swap(cells[c], cells[static_cast<int>(uniform01(rng) * (c + 1))]);
  }
  const double w = sensor.width_px, h = sensor.height_px;
  const double cell_w = (w - 2 * margin_px) / cols, cell_h = (h - 2 * margin_px) / rows;
  constexpr int kTriesPerCell = 40;
  for (int cell : cells) {
    if (static_cast<int>(truth.points_a_px.size()) >= count) break;
    const int cx = cell % cols, cy = cell / cols;
    for (int attempt = 0; attempt < kTriesPerCell; ++attempt) {
      const Eigen::Vector2d p_a(margin_px + (cx + uniform01(rng)) * cell_w - 0.5,
                                margin_px + (cy + uniform01(rng)) * cell_h - 0.5);
      const double t_a = camera.rowTime(stamp_a_s, p_a.y());
      const Eigen::Vector3d centre = camera.motion().pose(t_a).centre_world_m;
      SceneHit hit;
      if (!scene.intersect(centre, camera.rayDirectionWorld(p_a, t_a), t_a, &hit) || !hit.is_static) continue;
      Eigen::Vector2d p_b;
      double t_b = 0.0;
      if (!camera.projectRollingShutter(hit.point_world_m, stamp_b_s, &p_b, &t_b)) continue;
      if (p_b.x() < margin_px - 0.5 || p_b.y() < margin_px - 0.5 || p_b.x() > w - 0.5 - margin_px ||
          p_b.y() > h - 0.5 - margin_px) {
        continue;
      }
      if (!visibleAt(camera, scene, hit.point_world_m, hit.plane_index, t_b)) continue;
      truth.points_a_px.push_back(p_a);
      truth.points_b_px.push_back(p_b);
      break;
    }
  }
  return truth;
}

}  // namespace sim
}  // namespace deep_ois
