#include "deep_ois/core/common/matrix_exponential.h"

#include <cmath>

namespace deep_ois {

Eigen::Matrix3d matrixExponential(const Eigen::Matrix3d& M) {
  // Scale until the norm is at most 0.5, where 18 Taylor terms reach double precision.
  const double norm = M.cwiseAbs().rowwise().sum().maxCoeff();
  int squarings = 0;
  while (norm / std::ldexp(1.0, squarings) > 0.5) ++squarings;
  const Eigen::Matrix3d A = M / std::ldexp(1.0, squarings);
  Eigen::Matrix3d result = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d term = Eigen::Matrix3d::Identity();
  for (int n = 1; n <= 18; ++n) {
    term = term * A / n;
    result += term;
  }
  for (int i = 0; i < squarings; ++i) result = result * result;
  return result;
}

}  // namespace deep_ois
