#include "deep_ois/core/calibration/camera_imu_coarse_alignment.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/calibration/rotation_alignment.h"

namespace deep_ois {

Eigen::Vector3d fitImageRotation(const std::vector<Eigen::Vector3d>& bearings_a,
                                 const std::vector<Eigen::Vector3d>& bearings_b, double scale_rad,
                                 int* inlier_count) {
  if (bearings_a.size() != bearings_b.size() || bearings_a.size() < 3) {
    throw std::invalid_argument("fitImageRotation: needs two equally long lists of at least 3 bearings");
  }
  const std::size_t n = bearings_a.size();
  std::vector<double> weights(n, 1.0);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  // A handful of reweightings settle: the first (unweighted) fit is already close for the small
  // rotations between frames, and the Cauchy weights only have to discount the outliers.
  for (int iteration = 0; iteration < 6; ++iteration) {
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < n; ++k) M += weights[k] * bearings_b[k] * bearings_a[k].transpose();
    R = kabsch(M);
    for (std::size_t k = 0; k < n; ++k) {
      const double e2 = (bearings_b[k] - R * bearings_a[k]).squaredNorm() / (scale_rad * scale_rad);
      weights[k] = 1.0 / (1.0 + e2);
    }
  }
  if (inlier_count) {
    // Weight above 1/5 = within 2 scales.
    *inlier_count = static_cast<int>(std::count_if(weights.begin(), weights.end(),
                                                   [](double w) { return w > 0.2; }));
  }
  return logSO3(R);
}

namespace {

double cauchy(const Eigen::Vector3d& error, double scale) {
  return std::log1p(error.squaredNorm() / (scale * scale));
}

// The gyro's camera-independent rotation vector of a pair, -log(R_imu(t_a)^T R_imu(t_b)), at a
// time offset and readout; rotating it by R_cam_imu predicts the pair's image rotation
// log(R_b_a) (R_b_a = R_cam_imu delta^T R_cam_imu^T).
Eigen::Vector3d gyroRotationVector(const GyroOrientationTable& gyro, const CoarsePair& pair,
                                   double time_offset_s, double readout_time_s) {
  const double row_delay = readout_time_s * pair.mean_row_fraction;
  return -logSO3(gyro.relativeRotation(pair.stamp_a_s + time_offset_s + row_delay,
                                       pair.stamp_b_s + time_offset_s + row_delay));
}

}  // namespace

CoarseAlignment coarseCameraImuAlignment(const GyroOrientationTable& gyro,
                                         const std::vector<CoarsePair>& pairs,
                                         const CoarseAlignmentOptions& options) {
  const bool search_offset = options.max_abs_time_offset_s > 0.0;
  if (search_offset && !(options.time_step_s > 0.0 && options.time_step_s <= options.max_abs_time_offset_s)) {
    throw std::invalid_argument("coarse alignment: time_step_s must be in (0, max_abs_time_offset_s]");
  }
  if (!(options.scale_rad > 0.0) || !(options.readout_time_s >= 0.0)) {
    throw std::invalid_argument("coarse alignment: scale_rad must be positive and readout_time_s >= 0");
  }
  const int half_steps = search_offset
                             ? static_cast<int>(std::round(options.max_abs_time_offset_s / options.time_step_s))
                             : 0;
  const int offset_count = 2 * half_steps + 1;
  auto offsetAt = [&](double i) {
    return search_offset ? (i - half_steps) * options.time_step_s : options.held_time_offset_s;
  };

  // Only pairs the gyro covers at every offset, so every cell is scored on the same pairs.
  std::vector<const CoarsePair*> used;
  for (const CoarsePair& pair : pairs) {
    const double begin = pair.stamp_a_s + offsetAt(0);
    const double end = pair.stamp_b_s + offsetAt(offset_count - 1) + options.readout_time_s;
    if (gyro.coverage(begin, end).ok()) used.push_back(&pair);
  }
  if (used.empty()) {
    std::ostringstream why;
    why << "coarse alignment: the gyro covers none of the " << pairs.size()
        << " frame pairs over the whole offset range +-" << options.max_abs_time_offset_s << " s";
    throw std::invalid_argument(why.str());
  }

  // The gyro rotation of every pair at every offset, computed once for all permutations.
  std::vector<std::vector<Eigen::Vector3d>> gyro_vectors(offset_count);
  for (int i = 0; i < offset_count; ++i) {
    gyro_vectors[i].reserve(used.size());
    for (const CoarsePair* pair : used) {
      gyro_vectors[i].push_back(gyroRotationVector(gyro, *pair, offsetAt(i), options.readout_time_s));
    }
  }

  std::vector<Eigen::Matrix3d> candidates =
      options.search_rotation ? signedAxisPermutations() : std::vector<Eigen::Matrix3d>{options.held_rotation};
  CoarseAlignment result;
  result.pairs_used = static_cast<int>(used.size());
  result.cost_by_offset.assign(offset_count, std::numeric_limits<double>::infinity());
  result.cost_by_permutation.assign(candidates.size(), std::numeric_limits<double>::infinity());
  std::vector<std::vector<double>> costs(candidates.size(), std::vector<double>(offset_count));
  int best_i = 0, best_p = 0;
  for (std::size_t p = 0; p < candidates.size(); ++p) {
    for (int i = 0; i < offset_count; ++i) {
      double cost = 0.0;
      for (std::size_t k = 0; k < used.size(); ++k) {
        cost += cauchy(used[k]->image_rotation_rad - candidates[p] * gyro_vectors[i][k], options.scale_rad);
      }
      costs[p][i] = cost;
      result.cost_by_offset[i] = std::min(result.cost_by_offset[i], cost);
      result.cost_by_permutation[p] = std::min(result.cost_by_permutation[p], cost);
      if (cost < costs[best_p][best_i]) {
        best_p = static_cast<int>(p);
        best_i = i;
      }
    }
  }

  // Sub-step offset from the parabola through the best cell and its neighbours.
  double offset = offsetAt(best_i);
  if (best_i > 0 && best_i + 1 < offset_count) {
    const double left = costs[best_p][best_i - 1], centre = costs[best_p][best_i],
                 right = costs[best_p][best_i + 1];
    const double curvature = left - 2.0 * centre + right;
    if (curvature > 0.0) {
      offset += std::clamp(0.5 * (left - right) / curvature, -0.5, 0.5) * options.time_step_s;
    }
  }
  result.time_offset_s = offset;
  result.permutation_index = options.search_rotation ? best_p : -1;

  std::vector<Eigen::Vector3d> gyro_at_offset;
  for (const CoarsePair* pair : used) {
    gyro_at_offset.push_back(gyroRotationVector(gyro, *pair, offset, options.readout_time_s));
  }
  auto totalCost = [&](const Eigen::Matrix3d& R) {
    double cost = 0.0;
    for (std::size_t k = 0; k < used.size(); ++k) {
      cost += cauchy(used[k]->image_rotation_rad - R * gyro_at_offset[k], options.scale_rad);
    }
    return cost;
  };
  Eigen::Matrix3d R = candidates[best_p];
  double cost = totalCost(R);
  if (options.search_rotation) {
    // Procrustes on the pairs' rotation vectors, reweighted: the continuous rotation near the
    // permutation (a real mount is a few degrees off its nominal axes).
    Eigen::Matrix3d R_refined = R;
    for (int iteration = 0; iteration < 5; ++iteration) {
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      for (std::size_t k = 0; k < used.size(); ++k) {
        const Eigen::Vector3d error = used[k]->image_rotation_rad - R_refined * gyro_at_offset[k];
        const double w = 1.0 / (1.0 + error.squaredNorm() / (options.scale_rad * options.scale_rad));
        M += w * used[k]->image_rotation_rad * gyro_at_offset[k].transpose();
      }
      R_refined = kabsch(M);
    }
    const double refined_cost = totalCost(R_refined);
    if (refined_cost < cost) {
      R = R_refined;
      cost = refined_cost;
    }
  }
  result.imu_to_camera_rotation = R;
  result.cost = cost;

  // The bias each pair implies: image = R (gyro + bias * duration); median per axis over the
  // pairs that agree with the model.
  std::vector<double> implied[3];
  for (std::size_t k = 0; k < used.size(); ++k) {
    const Eigen::Vector3d error = used[k]->image_rotation_rad - R * gyro_at_offset[k];
    if (error.norm() > 2.0 * options.scale_rad) continue;
    const double duration = used[k]->stamp_b_s - used[k]->stamp_a_s;
    const Eigen::Vector3d bias = (R.transpose() * used[k]->image_rotation_rad - gyro_at_offset[k]) / duration;
    for (int axis = 0; axis < 3; ++axis) implied[axis].push_back(bias[axis]);
  }
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double>& values = implied[axis];
    if (values.empty()) continue;
    std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
    result.gyro_bias_rad_s[axis] = values[values.size() / 2];
  }
  return result;
}

}  // namespace deep_ois
