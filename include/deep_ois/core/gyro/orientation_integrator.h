// Integration of gyroscope angular velocity into an orientation change between two times.
#pragma once

#include <Eigen/Core>
#include <string>

#include "deep_ois/core/common/so3_and_statistics.h"  // expSO3, logSO3 (part of this API)
#include "deep_ois/core/gyro/imu_sample_buffer.h"

namespace deep_ois {

// How the angular velocity is modelled between two consecutive samples.
enum class RateInterpolation {
  // Rate varies linearly between samples. Each (sub-)interval is integrated with the exact
  // exponential map of its second-order Magnus rotation vector: the mean rate times the duration
  // plus the coning term dt^2/12 (w_start x w_end). Exact for a rate of constant direction and
  // third-order accurate otherwise.
  kLinear,
  // Rate held at sample k's value from stamp k until stamp k+1 (as most phone HAL code does);
  // each interval is one exact exponential map.
  kZeroOrderHold,
};

struct IntegrationOptions {
  RateInterpolation interpolation = RateInterpolation::kLinear;
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  // subtracted from every sample
  // Two consecutive samples further apart than this are a gap: integrating across it would
  // invent motion, so it is refused. Seconds.
  double max_sample_gap_s = 0.1;
};

enum class IntegrationStatus {
  kOk,
  kEmptyBuffer,
  kNotYetAvailable,  // the interval ends after the newest sample: wait for more IMU data
  kTooOld,           // the interval starts before the oldest buffered sample: will never be covered
  kGap,              // the interval crosses a gap longer than max_sample_gap_s
  kInvalidTime,      // a non-finite time was asked for
};

const char* toString(IntegrationStatus status);

// The orientation change R(t0)^T R(t1) of the IMU body frame from t0 to t1 (IMU clock, seconds),
// where R(t) maps body vectors to a fixed world frame. A world point seen in the body frame at t0
// is at rotation.transpose() * p in the body frame at t1. t1 < t0 gives the inverse rotation.
struct IntegrationResult {
  IntegrationStatus status = IntegrationStatus::kOk;
  std::string reason;  // empty when ok
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  bool ok() const { return status == IntegrationStatus::kOk; }
};

IntegrationResult integrateRotation(const ImuSampleBuffer& buffer, double t0_s, double t1_s,
                                    const IntegrationOptions& options);

// Whether [t0_s, t1_s] is integrable now; the same checks integrateRotation() makes.
IntegrationResult checkCoverage(const ImuSampleBuffer& buffer, double t0_s, double t1_s,
                                const IntegrationOptions& options);

// The modelled rate (bias removed, IMU frame, rad/s) at time t_s inside [before, after], two
// consecutive samples: what integrateRotation() integrates there.
Eigen::Vector3d rateAt(const ImuSample& before, const ImuSample& after, double t_s,
                       const IntegrationOptions& options);

}  // namespace deep_ois
