#include "deep_ois/core/calibration/rotation_alignment.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>

namespace deep_ois {

Eigen::Matrix3d kabsch(const Eigen::Matrix3d& M) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

const std::vector<Eigen::Matrix3d>& signedAxisPermutations() {
  static const std::vector<Eigen::Matrix3d> permutations = [] {
    std::vector<Eigen::Matrix3d> all;
    std::array<int, 3> columns = {0, 1, 2};
    do {
      for (int signs = 0; signs < 8; ++signs) {
        Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
        for (int row = 0; row < 3; ++row) P(row, columns[row]) = (signs >> (2 - row)) & 1 ? -1.0 : 1.0;
        // Half of the 48 signed permutations are reflections; a mount is a rotation.
        if (P.determinant() > 0.0) all.push_back(P);
      }
    } while (std::next_permutation(columns.begin(), columns.end()));
    return all;
  }();
  return permutations;
}

double rotationAngleBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  // trace(R) = 1 + 2 cos(angle); clamped against rounding just outside [-1, 1].
  const double cosine = std::clamp(((R_a.transpose() * R_b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(cosine);
}

int nearestSignedAxisPermutation(const Eigen::Matrix3d& R) {
  const std::vector<Eigen::Matrix3d>& all = signedAxisPermutations();
  int best = 0;
  double best_angle = rotationAngleBetween(all[0], R);
  for (int i = 1; i < static_cast<int>(all.size()); ++i) {
    const double angle = rotationAngleBetween(all[i], R);
    if (angle < best_angle) {
      best_angle = angle;
      best = i;
    }
  }
  return best;
}

}  // namespace deep_ois
