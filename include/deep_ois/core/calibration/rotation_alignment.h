// Aligning two frames' rotations: the orthogonal Procrustes solution and the discrete set of
// sensor mounts (signed axis permutations). Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace deep_ois {

// The proper rotation R maximising sum_k w_k b_k^T R a_k, given the weighted cross-covariance
// M = sum_k w_k b_k a_k^T (Kabsch's orthogonal Procrustes solution, det R = +1 enforced).
Eigen::Matrix3d kabsch(const Eigen::Matrix3d& M);

// The 24 proper signed axis permutations: every rotation whose entries are 0 or +-1, i.e. every
// way a sensor can be mounted with its axes along the camera's. Fixed order (rows of the
// permutation, then signs, lexicographic), so an index names a mount.
const std::vector<Eigen::Matrix3d>& signedAxisPermutations();

// Index into signedAxisPermutations() of the permutation closest to `R` (smallest rotation angle
// of R P^T).
int nearestSignedAxisPermutation(const Eigen::Matrix3d& R);

// Angle of the rotation R_a^T R_b, radians in [0, pi].
double rotationAngleBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b);

}  // namespace deep_ois
