#include "deep_ois/core/ois/lens_shift_homographies.h"

#include <Eigen/LU>
#include <stdexcept>

namespace deep_ois {

std::vector<Eigen::Matrix3d> lensShiftHomographies(const Eigen::Matrix3d& K,
                                                   const std::vector<Eigen::Matrix3d>& rotations,
                                                   const std::vector<Eigen::Vector2d>& shift_a_px,
                                                   const std::vector<Eigen::Vector2d>& shift_b_px) {
  if (shift_a_px.size() != rotations.size() || shift_b_px.size() != rotations.size()) {
    throw std::invalid_argument("lensShiftHomographies: one shift per rotation and frame needed");
  }
  std::vector<Eigen::Matrix3d> out;
  out.reserve(rotations.size());
  for (std::size_t i = 0; i < rotations.size(); ++i) {
    Eigen::Matrix3d K_a = K, K_b = K;
    K_a.block<2, 1>(0, 2) += shift_a_px[i];
    K_b.block<2, 1>(0, 2) += shift_b_px[i];
    const Eigen::Matrix3d H = K_b * rotations[i] * K_a.inverse();
    out.push_back(H / H(2, 2));
  }
  return out;
}

}  // namespace deep_ois
