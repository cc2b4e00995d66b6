// The image motion of an OIS camera whose lens shift is known: per row patch
// K(s_b,i) R_b_a,i K(s_a,i)^-1, where K(s) is K with its principal point moved by the lens shift s
// (pixels). The gyro gives R; the lens shift comes from a log (lens_shift_log.h) or an estimate
// (core/ground_truth/lens_shift_ground_truth.h).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

// K(s_b,i) R_i K(s_a,i)^-1 on undistorted pixels, H[2][2] = 1. Throws std::invalid_argument
// unless there is one shift per rotation in each frame.
std::vector<Eigen::Matrix3d> lensShiftHomographies(const Eigen::Matrix3d& K,
                                                   const std::vector<Eigen::Matrix3d>& rotations,
                                                   const std::vector<Eigen::Vector2d>& shift_a_px,
                                                   const std::vector<Eigen::Vector2d>& shift_b_px);

// Camera-clock time (seconds) of patch i of a frame stamped frame_stamp_s: the patch time the gyro
// integration uses (patchImuTime) without the camera-to-IMU time offset. A lens log is on the
// camera's clock (Android: the SENSOR_TIMESTAMP clock).
double patchCameraTime(const RollingShutterConfig& config, double frame_stamp_s, int patch_index);

// The first and last camera-clock times a pair needs from the lens log.
struct LensLogInterval {
  double begin_s;
  double end_s;
};
LensLogInterval lensLogInterval(const RollingShutterConfig& config, double stamp_a_s,
                                double stamp_b_s);

// The per-patch homographies of the pair (stamp_a_s, stamp_b_s) (camera-clock seconds, on the
// log's time base after its time offset) with the lens shift interpolated from `log` at each
// patch's capture time in both frames, and `rotations` the gyro's R_b_a per patch
// (RollingShutterHomographies::rotations). Empty when the log does not cover the pair.
std::optional<std::vector<Eigen::Matrix3d>> lensLogHomographies(
    const Eigen::Matrix3d& K, const std::vector<Eigen::Matrix3d>& rotations,
    const LensShiftLog& log, const RollingShutterConfig& config, double stamp_a_s,
    double stamp_b_s);

}  // namespace deep_ois
