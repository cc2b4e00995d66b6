#include "deep_ois/core/common/so3_and_statistics.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>

namespace deep_ois {

bool isProperRotation(const Eigen::Matrix3d& R) {
  return R.allFinite() && (R * R.transpose()).isIdentity(1e-6) && std::abs(R.determinant() - 1.0) <= 1e-6;
}

Eigen::Matrix3d expSO3(const Eigen::Vector3d& rotation_vector_rad) {
  const double angle = rotation_vector_rad.norm();
  const Eigen::Matrix3d S = skew(rotation_vector_rad);
  // Taylor series below 1e-4 rad keeps full double precision where sin(a)/a loses digits.
  double a, b;
  if (angle < 1e-4) {
    const double angle2 = angle * angle;
    a = 1.0 - angle2 / 6.0;
    b = 0.5 - angle2 / 24.0;
  } else {
    a = std::sin(angle) / angle;
    b = (1.0 - std::cos(angle)) / (angle * angle);
  }
  return Eigen::Matrix3d::Identity() + a * S + b * S * S;
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd angle_axis(rotation);
  return angle_axis.angle() * angle_axis.axis();
}

Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& rotation_vector_rad) {
  const double angle = rotation_vector_rad.norm();
  const Eigen::Matrix3d S = skew(rotation_vector_rad);
  // I + (1 - cos a) / a^2 S + (a - sin a) / a^3 S^2, by its series for small angles.
  double b, c;
  if (angle < 1e-4) {
    const double angle2 = angle * angle;
    b = 0.5 - angle2 / 24.0;
    c = 1.0 / 6.0 - angle2 / 120.0;
  } else {
    b = (1.0 - std::cos(angle)) / (angle * angle);
    c = (angle - std::sin(angle)) / (angle * angle * angle);
  }
  return Eigen::Matrix3d::Identity() + b * S + c * S * S;
}

}  // namespace deep_ois
