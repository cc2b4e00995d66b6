#include "deep_ois/core/gyro/imu_sample_buffer.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

ImuSampleBuffer::ImuSampleBuffer(double max_duration_s) : max_duration_s_(max_duration_s) {
  if (!(max_duration_s > 0.0) || !std::isfinite(max_duration_s)) {
    throw std::invalid_argument("ImuSampleBuffer: max_duration_s must be a positive number of seconds");
  }
}

ImuAddResult ImuSampleBuffer::add(const ImuSample& sample) {
  std::ostringstream why;
  why << std::fixed << std::setprecision(6);
  if (!std::isfinite(sample.stamp_s)) {
    why << "non-finite stamp (" << sample.stamp_s << ")";
    return {ImuSampleStatus::kNonFiniteStamp, why.str()};
  }
  if (!sample.angular_velocity_rad_s.allFinite()) {
    why << "non-finite angular velocity (" << sample.angular_velocity_rad_s.transpose()
        << ") rad/s at stamp " << sample.stamp_s << " s";
    return {ImuSampleStatus::kNonFiniteRate, why.str()};
  }
  if (!samples_.empty()) {
    const double newest = samples_.back().stamp_s;
    if (sample.stamp_s == newest) {
      why << "duplicate stamp " << sample.stamp_s << " s (already have a sample there)";
      return {ImuSampleStatus::kDuplicateStamp, why.str()};
    }
    if (sample.stamp_s < newest) {
      why << "out-of-order stamp " << sample.stamp_s << " s is " << std::setprecision(3)
          << (newest - sample.stamp_s) * 1e3 << " ms older than the newest sample "
          << std::setprecision(6) << newest << " s";
      return {ImuSampleStatus::kOutOfOrderStamp, why.str()};
    }
  }
  samples_.push_back(sample);
  // Keep at least two samples so that the newest interval stays integrable.
  while (samples_.size() > 2 && sample.stamp_s - samples_.front().stamp_s > max_duration_s_) {
    samples_.pop_front();
  }
  return {};
}

}  // namespace deep_ois
