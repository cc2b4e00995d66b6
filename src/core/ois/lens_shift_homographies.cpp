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
    Eigen::Matrix3d H = K_b * rotations[i] * K_a.inverse();
    out.push_back(H / H(2, 2));
  }
  return out;
}

double patchCameraTime(const RollingShutterConfig& config, double frame_stamp_s, int patch_index) {
  return patchImuTime(config, frame_stamp_s, patch_index) - config.time_offset_s;
}

LensLogInterval lensLogInterval(const RollingShutterConfig& config, double stamp_a_s,
                                double stamp_b_s) {
  return {patchCameraTime(config, stamp_a_s, 0),
          patchCameraTime(config, stamp_b_s, config.patch_count - 1)};
}

std::optional<std::vector<Eigen::Matrix3d>> lensLogHomographies(
    const Eigen::Matrix3d& K, const std::vector<Eigen::Matrix3d>& rotations,
    const LensShiftLog& log, const RollingShutterConfig& config, double stamp_a_s,
    double stamp_b_s) {
  if (static_cast<int>(rotations.size()) != config.patch_count) {
    throw std::invalid_argument("lensLogHomographies: one rotation per row patch needed");
  }
  const LensLogInterval needed = lensLogInterval(config, stamp_a_s, stamp_b_s);
  if (!log.covers(needed.begin_s, needed.end_s)) return std::nullopt;
  std::vector<Eigen::Vector2d> shift_a, shift_b;
  for (int i = 0; i < config.patch_count; ++i) {
    shift_a.push_back(log.shiftAt(patchCameraTime(config, stamp_a_s, i)));
    shift_b.push_back(log.shiftAt(patchCameraTime(config, stamp_b_s, i)));
  }
  return lensShiftHomographies(K, rotations, shift_a, shift_b);
}

}  // namespace deep_ois
