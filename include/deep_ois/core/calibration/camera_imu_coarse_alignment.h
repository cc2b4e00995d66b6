// The global stage of the camera-IMU calibration: time offset and IMU-to-camera rotation without
// an initial guess. Each frame pair's tracks give one camera rotation (a rotation-only fit, the
// rolling shutter ignored); the gyro gives one for every candidate time offset. A grid over the
// offset times all 24 signed axis permutations (the ways a sensor is mounted) scores their
// agreement with a robust loss; the best cell is refined by Procrustes to the continuous rotation
// (the few degrees a mount is off its nominal axes) and gives a starting gyro bias. Pure Eigen.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deep_ois/core/gyro/gyro_orientation_table.h"

namespace deep_ois {

// Rotation-only fit of one pair's tracks (unit bearing vectors K^-1 x of the undistorted pixels,
// a -> b) by iteratively reweighted Kabsch with a Cauchy loss at `scale_rad` (angle between
// bearings). Returns log(R_b_a) in the camera frame, radians; `inlier_count` (optional) receives
// the tracks within 2 scales. Throws std::invalid_argument when the lists differ in length or
// hold fewer than 3 tracks.
Eigen::Vector3d fitImageRotation(const std::vector<Eigen::Vector3d>& bearings_a,
                                 const std::vector<Eigen::Vector3d>& bearings_b, double scale_rad,
                                 int* inlier_count = nullptr);

// One frame pair as the coarse stage sees it.
struct CoarsePair {
  double stamp_a_s = 0.0;            // camera clock, first row
  double stamp_b_s = 0.0;
  double mean_row_fraction = 0.5;    // mean v / height of the tracks: their mean capture row
  Eigen::Vector3d image_rotation_rad = Eigen::Vector3d::Zero();  // fitImageRotation()
};

struct CoarseAlignmentOptions {
  // Offset grid [-max, +max] (IMU time = camera stamp + offset); a non-positive max means the
  // offset is held at held_time_offset_s.
  double max_abs_time_offset_s = 0.2;
  double time_step_s = 0.001;
  double held_time_offset_s = 0.0;
  // Readout time assumed while searching (the refinement estimates it); the offset found absorbs
  // (true - assumed) x the mean row fraction.
  double readout_time_s = 0.0;
  // When false, only `held_rotation` is scored (no permutation search, no Procrustes).
  bool search_rotation = true;
  Eigen::Matrix3d held_rotation = Eigen::Matrix3d::Identity();
  // Cauchy scale of the rotation disagreement, radians (about 1 px at the focal length).
  double scale_rad = 0.003;
};

struct CoarseAlignment {
  double time_offset_s = 0.0;
  int permutation_index = -1;  // into signedAxisPermutations(); -1 when the rotation was held
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();  // Procrustes-refined
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  // median implied bias, IMU frame
  int pairs_used = 0;  // pairs the gyro covers at every offset of the grid
  double cost = 0.0;   // robust cost of the best cell (sum over pairs of log(1 + e^2 / scale^2))
  // Best cost over permutations at each grid offset (offset_i = -max + i * step), and the best
  // cost of each permutation over offsets: the landscape, for diagnosis and tests.
  std::vector<double> cost_by_offset;
  std::vector<double> cost_by_permutation;
};

// Scores every (offset, permutation) cell on the pairs the gyro table covers over the whole grid.
// `gyro` should hold a zero bias (the bias is what the stage estimates). Throws
// std::invalid_argument when no pair is covered or an option is out of range.
CoarseAlignment coarseCameraImuAlignment(const GyroOrientationTable& gyro,
                                         const std::vector<CoarsePair>& pairs,
                                         const CoarseAlignmentOptions& options);

}  // namespace deep_ois
