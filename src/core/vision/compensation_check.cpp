#include "deep_ois/core/vision/compensation_check.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {
namespace {

double transferError(const Eigen::Matrix3d& H, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d p = H * a.homogeneous();
  return (p.hnormalized() - b).norm();
}

}  // namespace

std::string CompensationCheckOptions::validate() const {
  std::ostringstream why;
  if (!(outlier_px > 0.0)) why << "outlier_px must be positive (got " << outlier_px << ")";
  else if (min_inliers < 1) why << "min_inliers must be at least 1 (got " << min_inliers << ")";
  else if (confident_inliers < min_inliers)
    why << "confident_inliers (" << confident_inliers << ") must be at least min_inliers (" << min_inliers << ")";
  return why.str();
}

CompensationCheck checkCompensation(const CameraModel& camera, const std::vector<FeatureMatch>& matches,
                                    const std::vector<Eigen::Matrix3d>& model_homographies,
                                    const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                    const CompensationCheckOptions& options) {
  if (model_homographies.empty() || model_homographies.size() != gyro_homographies.size())
    throw std::invalid_argument("checkCompensation: " + std::to_string(model_homographies.size()) +
                                " model and " + std::to_string(gyro_homographies.size()) +
                                " gyro homographies (one per row patch, the same count)");
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("checkCompensation: " + problem);
  const int patches = static_cast<int>(model_homographies.size());
  CompensationCheck check;
  check.tracks = static_cast<int>(matches.size());
  double model_sum = 0.0, gyro_sum = 0.0;
  for (const FeatureMatch& m : matches) {
    const Eigen::Vector2d a = camera.undistort(Eigen::Vector2d(m.point_a_px.x, m.point_a_px.y));
    const Eigen::Vector2d b = camera.undistort(Eigen::Vector2d(m.point_b_px.x, m.point_b_px.y));
    const auto patch = static_cast<std::size_t>(patchIndexOfRow(m.point_a_px.y, camera.height(), patches));
    const double model_error = transferError(model_homographies[patch], a, b);
    const double gyro_error = transferError(gyro_homographies[patch], a, b);
    if (!std::isfinite(model_error) || !std::isfinite(gyro_error)) continue;
    if (std::min(model_error, gyro_error) > options.outlier_px) continue;
    // Both capped at the outlier threshold: one track the model misses by metres must not decide.
    model_sum += std::min(model_error, options.outlier_px);
    gyro_sum += std::min(gyro_error, options.outlier_px);
    ++check.inliers;
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  check.usable = check.inliers >= options.min_inliers;
  if (!check.usable) {
    check.model_residual_px = check.gyro_residual_px = nan;
    return check;
  }
  check.model_residual_px = model_sum / check.inliers;
  check.gyro_residual_px = gyro_sum / check.inliers;
  check.confidence = (static_cast<double>(check.inliers) / check.tracks) *
                     std::min(1.0, static_cast<double>(check.inliers) / options.confident_inliers);
  return check;
}

CompensationComparison compareCompensations(const CameraModel& camera, const std::vector<FeatureMatch>& matches,
                                            const std::vector<std::vector<Eigen::Matrix3d>>& compensations,
                                            const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                            const CompensationCheckOptions& options) {
  for (const auto& homographies : compensations)
    if (homographies.empty() || homographies.size() != gyro_homographies.size())
      throw std::invalid_argument("compareCompensations: " + std::to_string(homographies.size()) + " and " +
                                  std::to_string(gyro_homographies.size()) +
                                  " gyro homographies (one per row patch, the same count)");
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("compareCompensations: " + problem);
  const int patches = static_cast<int>(gyro_homographies.size());
  const std::size_t n = compensations.size();
  CompensationComparison comparison;
  comparison.tracks = static_cast<int>(matches.size());
  std::vector<double> sums(n, 0.0), errors(n + 1);
  double gyro_sum = 0.0;
  for (const FeatureMatch& m : matches) {
    const Eigen::Vector2d a = camera.undistort(Eigen::Vector2d(m.point_a_px.x, m.point_a_px.y));
    const Eigen::Vector2d b = camera.undistort(Eigen::Vector2d(m.point_b_px.x, m.point_b_px.y));
    const auto patch = static_cast<std::size_t>(patchIndexOfRow(m.point_a_px.y, camera.height(), patches));
    bool finite = true;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k <= n; ++k) {
      errors[k] = transferError(k < n ? compensations[k][patch] : gyro_homographies[patch], a, b);
      finite = finite && std::isfinite(errors[k]);
      best = std::min(best, errors[k]);
    }
    if (!finite || best > options.outlier_px) continue;
    // Capped at the outlier threshold, as in checkCompensation.
    for (std::size_t k = 0; k < n; ++k) sums[k] += std::min(errors[k], options.outlier_px);
    gyro_sum += std::min(errors[n], options.outlier_px);
    ++comparison.inliers;
  }
  comparison.usable = comparison.inliers >= options.min_inliers;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t k = 0; k < n; ++k)
    comparison.residuals_px.push_back(comparison.usable ? sums[k] / comparison.inliers : nan);
  comparison.gyro_residual_px = comparison.usable ? gyro_sum / comparison.inliers : nan;
  return comparison;
}

bool CompensationFallback::update(const CompensationCheck& check) {
  if (!check.usable) return falling_back_;
  const bool worse = check.model_residual_px >
                     check.gyro_residual_px * (1.0 + options_.worse_fraction) + options_.margin_px;
  // Counts pairs pointing away from the current state; one pair the other way restarts it.
  if (worse != falling_back_) {
    ++streak_;
    if (streak_ >= (falling_back_ ? options_.leave_after_pairs : options_.enter_after_pairs)) {
      falling_back_ = !falling_back_;
      streak_ = 0;
    }
  } else {
    streak_ = 0;
  }
  return falling_back_;
}

}  // namespace deep_ois
