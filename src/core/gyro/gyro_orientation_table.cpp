#include "deep_ois/core/gyro/gyro_orientation_table.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace deep_ois {

GyroOrientationTable::GyroOrientationTable(const ImuSampleBuffer& buffer,
                                           const IntegrationOptions& options)
    : buffer_(buffer), options_(options) {
  if (buffer_.size() < 2) {
    throw std::invalid_argument("gyro orientation table: needs at least two IMU samples, got " +
                                std::to_string(buffer_.size()));
  }
  // Gaps are integrated like any interval here (the table must stay defined everywhere);
  // coverage() is what refuses intervals that cross one.
  IntegrationOptions no_gap_check = options_;
  no_gap_check.max_sample_gap_s = std::numeric_limits<double>::infinity();
  stamps_s_.reserve(buffer_.size());
  orientations_.reserve(buffer_.size());
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  const auto& samples = buffer_.samples();
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (k > 0) {
      R = R * integrateRotation(buffer_, samples[k - 1].stamp_s, samples[k].stamp_s, no_gap_check).rotation;
    }
    stamps_s_.push_back(samples[k].stamp_s);
    orientations_.push_back(R);
  }
  options_.max_sample_gap_s = options.max_sample_gap_s;
}

IntegrationResult GyroOrientationTable::coverage(double t0_s, double t1_s) const {
  return checkCoverage(buffer_, t0_s, t1_s, options_);
}

std::size_t GyroOrientationTable::intervalOf(double t_s) const {
  const auto it = std::upper_bound(stamps_s_.begin(), stamps_s_.end(), t_s);
  const std::size_t after = static_cast<std::size_t>(it - stamps_s_.begin());
  return std::clamp<std::size_t>(after, 1, stamps_s_.size() - 1) - 1;
}

Eigen::Matrix3d GyroOrientationTable::orientation(double t_s) const {
  const double t = std::clamp(t_s, stamps_s_.front(), stamps_s_.back());
  const std::size_t k = intervalOf(t);
  if (t == stamps_s_[k]) return orientations_[k];
  IntegrationOptions no_gap_check = options_;
  no_gap_check.max_sample_gap_s = std::numeric_limits<double>::infinity();
  return orientations_[k] * integrateRotation(buffer_, stamps_s_[k], t, no_gap_check).rotation;
}

Eigen::Vector3d GyroOrientationTable::rate(double t_s) const {
  const double t = std::clamp(t_s, stamps_s_.front(), stamps_s_.back());
  const std::size_t k = intervalOf(t);
  return rateAt(buffer_.samples()[k], buffer_.samples()[k + 1], t, options_);
}

}  // namespace deep_ois
