// The image motion of an OIS camera between two frames: per row patch, K(s_b) R K(s_a)^-1, where
// K(s) is K with its principal point moved by the lens shift s (pixels). The gyro gives R; the
// lens shifts come from a stabiliser model, a lens log or the images (ground truth).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace deep_ois {

// The OIS camera's per-patch motion K(s_b,i) R_i K(s_a,i)^-1 on undistorted pixels, H[2][2] = 1.
// Throws std::invalid_argument unless there is one shift per rotation and frame.
std::vector<Eigen::Matrix3d> lensShiftHomographies(const Eigen::Matrix3d& K,
                                                   const std::vector<Eigen::Matrix3d>& rotations,
                                                   const std::vector<Eigen::Vector2d>& shift_a_px,
                                                   const std::vector<Eigen::Vector2d>& shift_b_px);

}  // namespace deep_ois
