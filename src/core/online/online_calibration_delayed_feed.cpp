#include "deep_ois/core/online/online_calibration_delayed_feed.h"

namespace deep_ois {

std::vector<OnlineCalibrationPair> DelayedCalibrationFeed::feed(const OnlineFramePair& pair,
                                                               OnlineCalibrationEstimator& estimator, bool* changed) {
  if (changed) *changed = false;
  if (pair.stamp_b_s == last_stamp_b_s_) {
    ++dropped_;
    ++repeats_;  // a repeat: its gyro and tracks are in already
    return {};
  }
  if (pair.stamp_b_s < last_stamp_b_s_) {
    // Another timeline (a replay looped) the caller did not clear: the estimator would ignore its
    // older pairs and gyro for good.
    clear();
    estimator.restartTimeline();
  }
  last_stamp_b_s_ = pair.stamp_b_s;
  const Eigen::Matrix3d camera_to_imu = pair.timing.imu_to_camera_rotation.transpose();
  for (const CameraRateSample& rate : pair.rates) {
    // Samples the estimator already has (each message repeats the warm-up) are ignored by it.
    estimator.addGyro({rate.stamp_s, camera_to_imu * rate.rate_rad_s});
    if (rate.stamp_s > gyro_end_s_) gyro_end_s_ = rate.stamp_s;
  }
  OnlineCalibrationPair out;
  out.stamp_a_s = pair.stamp_a_s;
  out.stamp_b_s = pair.stamp_b_s;
  if (pair.tracked) out.matches = pair.matches;
  waiting_.push_back(std::move(out));
  std::vector<OnlineCalibrationPair> added;
  const double offset_s = estimator.status().estimate.time_offset_s;
  while (!waiting_.empty() && waiting_.front().stamp_b_s + offset_s + coverage_s_ <= gyro_end_s_) {
    added.push_back(waiting_.front());
    estimator.addPair(std::move(waiting_.front()));
    waiting_.pop_front();
  }
  bool any = false;
  while (estimator.update()) any = true;
  if (changed) *changed = any;
  return added;
}

void DelayedCalibrationFeed::clear() {
  dropped_ += waiting_.size();
  waiting_.clear();
  gyro_end_s_ = -1e300;
  last_stamp_b_s_ = -1e300;
}

}  // namespace deep_ois
