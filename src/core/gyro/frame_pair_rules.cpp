#include "deep_ois/core/gyro/frame_pair_rules.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace deep_ois {

namespace {
constexpr std::size_t kIntervalHistory = 9;  // frame intervals behind the typical interval
// A pair this many typical intervals long lost a frame in between.
constexpr double kSpanningFactor = 1.5;
}  // namespace

FramePairRules::FramePairRules(const FramePairLimits& limits) : limits_(limits) {}

FramePairCheck FramePairRules::check(double previous_s, double frame_s, bool same_camera) const {
  if (frame_s - previous_s > limits_.max_frame_interval_s) return FramePairCheck::kTooFarApart;
  if (!same_camera) return FramePairCheck::kCameraChanged;
  return FramePairCheck::kPair;
}

bool FramePairRules::imuMayStillCome(IntegrationStatus status) {
  return status == IntegrationStatus::kNotYetAvailable || status == IntegrationStatus::kEmptyBuffer;
}

FrameWait FramePairRules::imuWait(IntegrationStatus status, double waited_s, double imu_quiet_s) const {
  if (status == IntegrationStatus::kOk) return FrameWait::kProceed;
  if (imu_quiet_s < 0.0) imu_quiet_s = waited_s;
  if (imuMayStillCome(status) &&
      (waited_s < limits_.imu_wait_timeout_s || imu_quiet_s < limits_.imu_wait_timeout_s)) {
    return FrameWait::kWait;
  }
  return FrameWait::kGiveUp;
}

FrameWait FramePairRules::lensLogWait(double log_newest_s, double needed_end_s, double waited_s,
                                      double log_quiet_s) const {
  if (log_newest_s < needed_end_s && waited_s < limits_.lens_wait_timeout_s &&
      log_quiet_s < limits_.lens_wait_timeout_s) {
    return FrameWait::kWait;
  }
  return FrameWait::kProceed;
}

void FramePairRules::accepted(double interval_s) {
  intervals_s_.push_back(interval_s);
  if (intervals_s_.size() > kIntervalHistory) intervals_s_.pop_front();
}

double FramePairRules::typicalIntervalS() const {
  if (intervals_s_.size() < 3) return 0.0;
  std::vector<double> sorted(intervals_s_.begin(), intervals_s_.end());
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  return sorted[sorted.size() / 2];
}

int FramePairRules::spannedIntervals(double interval_s) const {
  const double typical_s = typicalIntervalS();
  if (!(typical_s > 0.0) || !(interval_s > kSpanningFactor * typical_s)) return 0;
  return static_cast<int>(std::lround(interval_s / typical_s));
}

}  // namespace deep_ois
