// The camera-frame gyro rate at any time of a recorded rate stream, for callers that step through
// time in increasing order (a controller's or an integrator's fixed steps): the stabiliser oracle's
// control steps and the stabiliser fit's residual-bank steps walk their stream once with it.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"  // CameraRateSample

namespace deep_ois {

class CameraRateCursor {
 public:
  // `rates`: non-empty, stamps increasing; kept by reference (it must outlive the cursor).
  explicit CameraRateCursor(const std::vector<CameraRateSample>& rates) : rates_(rates) {}

  // The rate (rad/s, camera optical frame) at t_s: linear between the samples around it, held at
  // the first sample before it and at the last after it. t_s must not decrease from one call to
  // the next (the cursor only moves forward).
  Eigen::Vector3d at(double t_s) {
    while (next_ < rates_.size() && rates_[next_].stamp_s < t_s) ++next_;
    if (next_ >= rates_.size()) return rates_.back().rate_rad_s;
    const CameraRateSample& before = rates_[next_ - 1];
    const CameraRateSample& after = rates_[next_];
    if (t_s <= before.stamp_s) return before.rate_rad_s;
    const double alpha = (t_s - before.stamp_s) / (after.stamp_s - before.stamp_s);
    return (1.0 - alpha) * before.rate_rad_s + alpha * after.rate_rad_s;
  }

 private:
  const std::vector<CameraRateSample>& rates_;
  std::size_t next_ = 1;  // the first sample not before the last time asked
};

}  // namespace deep_ois
