// Small SO(3) and statistics helpers shared by the gyro integration, the ground truth and the
// calibration: one definition each. Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <vector>

namespace deep_ois {

// The cross-product matrix [v]x: skew(v) * w = v x w.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(),  //
      v.z(), 0.0, -v.x(),   //
      -v.y(), v.x(), 0.0;
  return S;
}

// Whether `R` is a proper rotation: finite, orthonormal and det +1 (to 1e-6).
bool isProperRotation(const Eigen::Matrix3d& R);

// The exponential map of so(3) (Rodrigues' formula), accurate for small angles too.
Eigen::Matrix3d expSO3(const Eigen::Vector3d& rotation_vector_rad);

// The inverse of expSO3 for angles below pi; returns the rotation vector in radians.
Eigen::Vector3d logSO3(const Eigen::Matrix3d& rotation);

// The left Jacobian of SO(3) at rotation vector v: expSO3(v + dv) = expSO3(J dv) expSO3(v) to
// first order. It turns a derivative along left perturbations into one along the rotation vector.
Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& rotation_vector_rad);

// The median of `values`, taken by value (partially reordered). For an even count it is the upper
// of the two middle values (one element of the sample, no averaging: robust scales and residual
// medians then stay actual residuals). 0 for an empty sample: callers that must tell "no data"
// apart check emptiness first.
inline double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace deep_ois
