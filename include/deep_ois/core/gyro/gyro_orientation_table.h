// The IMU orientation at every gyro sample, integrated once, so that the rotation between any two
// times costs two sub-interval integrations instead of one over the whole interval. For
// estimators that evaluate many (time, time) pairs per iteration, e.g. the camera-IMU calibration
// with one capture time per tracked point. Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/orientation_integrator.h"

namespace deep_ois {

class GyroOrientationTable {
 public:
  // Integrates every interval of `buffer` with `options` (interpolation and bias) by
  // integrateRotation(), so the table follows exactly the gyro flow's rate model. Keeps its own
  // copy of the samples. Throws std::invalid_argument with fewer than two samples.
  GyroOrientationTable(const ImuSampleBuffer& buffer, const IntegrationOptions& options);

  double beginTime() const { return buffer_.oldestStamp(); }  // IMU clock, seconds
  double endTime() const { return buffer_.newestStamp(); }
  const IntegrationOptions& options() const { return options_; }
  const ImuSampleBuffer& buffer() const { return buffer_; }

  // Whether [t0_s, t1_s] lies inside the samples without a gap (checkCoverage's rules). The
  // lookups below do not check: call this once per interval of interest.
  IntegrationResult coverage(double t0_s, double t1_s) const;

  // R(t) of the IMU body relative to its orientation at the first sample; t is clamped to
  // [beginTime(), endTime()].
  Eigen::Matrix3d orientation(double t_s) const;
  // R(t0)^T R(t1), the rotation integrateRotation(buffer, t0, t1) returns (to rounding).
  Eigen::Matrix3d relativeRotation(double t0_s, double t1_s) const {
    return orientation(t0_s).transpose() * orientation(t1_s);
  }
  // The modelled body rate at t (bias removed), rad/s, IMU frame; t clamped like orientation().
  Eigen::Vector3d rate(double t_s) const;

 private:
  // Index k of the interval [stamp_k, stamp_k+1] holding t (clamped to the first/last interval).
  std::size_t intervalOf(double t_s) const;

  ImuSampleBuffer buffer_;
  IntegrationOptions options_;
  std::vector<double> stamps_s_;
  std::vector<Eigen::Matrix3d> orientations_;  // R(stamp_k)
};

}  // namespace deep_ois
