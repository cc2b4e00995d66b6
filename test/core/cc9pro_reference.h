// The cc9pro phone recording (../shared/data/cc9pro) and the authors' settings for their gyro
// homographies, shared by the tests that cross-check against them (the core path and the
// converted bag).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <string>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "npy_reader.h"

namespace deep_ois {
namespace test {

// DEEP_OIS_SHARED_DATA (environment) overrides the build-time default.
inline std::string cc9proDir() {
  const char* override_dir = std::getenv("DEEP_OIS_SHARED_DATA");
  const std::string base = override_dir && *override_dir ? override_dir : DEEP_OIS_SHARED_DATA_DIR;
  return base + "/cc9pro";
}

inline bool fileExists(const std::string& path) { return std::ifstream(path).good(); }

constexpr int kCc9proWidthPx = 800;
constexpr int kCc9proHeightPx = 600;
// The frames shipped with the recording, and the pairs (n-1 -> n) of the authors' homographies.
constexpr int kCc9proFirstFrame = 99;
constexpr int kCc9proLastFrame = 150;
constexpr int kAuthorsFirstPair = 100;  // gyro_homo_h33_source.npy holds pairs n = 100..200
constexpr int kAuthorsPairCount = 101;

inline Eigen::Matrix3d cc9proK() {
  Eigen::Matrix3d K;
  K << 573.8534, -0.6974, 406.0101,  //
      0.0, 575.0448, 309.0112,       //
      0.0, 0.0, 1.0;
  return K;
}

// The authors' settings for gyro_homo_h33_source.npy (see the data README).
inline RollingShutterConfig authorsConfig() {
  RollingShutterConfig config;
  config.patch_count = 10;
  config.readout_time_s = 0.033312;  // they set readout = frame period
  config.time_offset_s = 0.0;
  config.patch_time = PatchTimeReference::kPatchStart;
  // They build the rotation axis as (wy, wx, wz): the swap S = [[0,1,0],[1,0,0],[0,0,1]], det -1.
  // For any orthogonal Q, Q [v]x Q^T = det(Q) [Q v]x, so their per-step rotation
  // exp([S w dt]x) = S exp([w dt]x)^T S^T. Our R_b_a = R_cam_imu delta^T R_cam_imu^T is made of the
  // same transposed steps, so R_cam_imu = S would match, but S is improper. R_cam_imu enters twice,
  // so -S conjugates identically and is proper (det(-S) = (-1)^3 det(S) = +1). Found by trying all
  // 24 proper signed axis permutations: this one is the only one with a mean below 1 px (next best
  // 1.84 px).
  config.imu_to_camera_rotation << 0, -1, 0,  //
      -1, 0, 0,                               //
      0, 0, -1;
  return config;
}

inline IntegrationOptions authorsIntegration() {
  IntegrationOptions options;
  options.interpolation = RateInterpolation::kZeroOrderHold;
  return options;
}

// The authors' homography of pair n-1 -> n, patch `patch` (gyro_homo_h33_source.npy, 101x10x9).
inline Eigen::Matrix3d authorsHomography(const NpyArray& reference, int n, int patch) {
  Eigen::Matrix3d H;
  for (int e = 0; e < 9; ++e) H(e / 3, e % 3) = reference.at(n - kAuthorsFirstPair, patch, e);
  return H;
}

// How far our homographies put the four image corners from where the authors' put them (the
// difference of the displacements is the difference of the mapped positions), over many patches.
struct CornerDifference {
  double sum_px = 0.0;
  double max_px = 0.0;
  int count = 0;

  void add(const Eigen::Matrix3d& ours, const Eigen::Matrix3d& theirs) {
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(kCc9proWidthPx - 1.0, 0.0),
                                     Eigen::Vector2d(0.0, kCc9proHeightPx - 1.0),
                                     Eigen::Vector2d(kCc9proWidthPx - 1.0, kCc9proHeightPx - 1.0)}) {
      const double d = ((ours * p.homogeneous()).hnormalized() - (theirs * p.homogeneous()).hnormalized()).norm();
      sum_px += d;
      max_px = std::max(max_px, d);
      ++count;
    }
  }
  double meanPx() const { return count > 0 ? sum_px / count : 0.0; }
};

}  // namespace test
}  // namespace deep_ois
