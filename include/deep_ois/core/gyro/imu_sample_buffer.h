// A time-ordered, duration-bounded buffer of gyroscope samples. Pure C++/Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <string>

namespace deep_ois {

// One gyroscope reading, in the IMU's own frame.
struct ImuSample {
  double stamp_s = 0.0;                                          // IMU clock, seconds
  Eigen::Vector3d angular_velocity_rad_s = Eigen::Vector3d::Zero();  // rad/s, IMU frame
};

enum class ImuSampleStatus {
  kAccepted,
  kNonFiniteStamp,
  kNonFiniteRate,
  kDuplicateStamp,
  kOutOfOrderStamp,
};

// Outcome of ImuSampleBuffer::add(); `reason` is a sentence the caller can log as is.
struct ImuAddResult {
  ImuSampleStatus status = ImuSampleStatus::kAccepted;
  std::string reason;
  bool accepted() const { return status == ImuSampleStatus::kAccepted; }
};

// Keeps the samples of the last `max_duration_s` seconds (measured from the newest sample), in
// strictly increasing stamp order. Integration needs every sample between two frames, so the
// buffer keeps the whole stream rather than pairs. Not thread-safe: the owner serialises access.
class ImuSampleBuffer {
 public:
  explicit ImuSampleBuffer(double max_duration_s = 2.0);

  // Appends a sample. Rejects (and leaves the buffer unchanged for) non-finite stamps or rates,
  // a stamp equal to the newest one, and a stamp older than the newest one.
  ImuAddResult add(const ImuSample& sample);

  void clear() { samples_.clear(); }
  bool empty() const { return samples_.empty(); }
  std::size_t size() const { return samples_.size(); }
  double maxDurationSeconds() const { return max_duration_s_; }

  // Stamps of the oldest and newest samples; only valid when !empty().
  double oldestStamp() const { return samples_.front().stamp_s; }
  double newestStamp() const { return samples_.back().stamp_s; }

  const std::deque<ImuSample>& samples() const { return samples_; }

 private:
  double max_duration_s_;
  std::deque<ImuSample> samples_;
};

}  // namespace deep_ois
