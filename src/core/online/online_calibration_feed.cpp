#include "deep_ois/core/online/online_calibration_feed.h"

namespace deep_ois {

bool feedTrackedPair(const OnlineFramePair& pair, OnlineCalibrationEstimator& estimator) {
  const Eigen::Matrix3d camera_to_imu = pair.timing.imu_to_camera_rotation.transpose();
  for (const CameraRateSample& rate : pair.rates) {
    // Samples the estimator already has (each message repeats the warm-up) are ignored by it.
    estimator.addGyro({rate.stamp_s, camera_to_imu * rate.rate_rad_s});
  }
  OnlineCalibrationPair out;
  out.stamp_a_s = pair.stamp_a_s;
  out.stamp_b_s = pair.stamp_b_s;
  if (pair.tracked) out.matches = pair.matches;
  estimator.addPair(std::move(out));
  bool changed = false;
  while (estimator.update()) changed = true;
  return changed;
}

}  // namespace deep_ois
