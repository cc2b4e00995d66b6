#include "deep_ois/core/camera/camera_model.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <sstream>

namespace deep_ois {

CameraModel::CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K,
                         const std::vector<double>& plumb_bob)
    : width_px_(width_px), height_px_(height_px), K_(K) {
  for (std::size_t i = 0; i < plumb_bob.size() && i < 5; ++i) distortion_[i] = plumb_bob[i];
  has_distortion_ = !distortion_.isZero(0.0);
  if (K_.allFinite() && std::abs(K_.determinant()) > 0.0) K_inv_ = K_.inverse();
}

std::string CameraModel::validate() const {
  std::ostringstream why;
  if (width_px_ <= 0 || height_px_ <= 0) {
    why << "image size " << width_px_ << "x" << height_px_ << " is not positive";
  } else if (!K_.allFinite() || !distortion_.allFinite()) {
    why << "intrinsics or distortion contain non-finite values";
  } else if (!(K_(0, 0) > 0.0) || !(K_(1, 1) > 0.0)) {
    why << "focal lengths fx=" << K_(0, 0) << ", fy=" << K_(1, 1) << " must be positive";
  } else if (K_(1, 0) != 0.0 || K_(2, 0) != 0.0 || K_(2, 1) != 0.0 || K_(2, 2) != 1.0) {
    why << "intrinsic matrix K must be upper triangular with K[2][2] = 1";
  }
  return why.str();
}

Eigen::Vector2d CameraModel::distortNormalised(const Eigen::Vector2d& xy,
                                               Eigen::Matrix2d* jacobian) const {
  const double k1 = distortion_[0], k2 = distortion_[1], p1 = distortion_[2], p2 = distortion_[3],
               k3 = distortion_[4];
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const Eigen::Vector2d out(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
  if (jacobian != nullptr) {
    const double dradial_dr2 = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
    (*jacobian)(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x;
    (*jacobian)(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
    (*jacobian)(1, 0) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
    (*jacobian)(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x;
  }
  return out;
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& undistorted_px) const {
  if (!has_distortion_) return undistorted_px;
  const Eigen::Vector3d normalised = K_inv_ * undistorted_px.homogeneous();
  const Eigen::Vector2d distorted = distortNormalised(normalised.hnormalized(), nullptr);
  return (K_ * distorted.homogeneous()).hnormalized();
}

Eigen::Vector2d CameraModel::undistort(const Eigen::Vector2d& distorted_px) const {
  if (!has_distortion_) return distorted_px;
  const Eigen::Vector2d target = (K_inv_ * distorted_px.homogeneous()).hnormalized();
  Eigen::Vector2d xy = target;  // the distortion is small: start from the distorted point
  for (int iteration = 0; iteration < 20; ++iteration) {
    Eigen::Matrix2d jacobian;
    const Eigen::Vector2d residual = distortNormalised(xy, &jacobian) - target;
    const Eigen::Vector2d step = jacobian.lu().solve(residual);
    xy -= step;
    if (step.squaredNorm() < 1e-24) break;
  }
  return (K_ * xy.homogeneous()).hnormalized();
}

bool CameraModel::operator==(const CameraModel& other) const {
  return width_px_ == other.width_px_ && height_px_ == other.height_px_ && K_ == other.K_ &&
         distortion_ == other.distortion_;
}

}  // namespace deep_ois
