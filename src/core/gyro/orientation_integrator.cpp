#include "deep_ois/core/gyro/orientation_integrator.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace deep_ois {

const char* toString(IntegrationStatus status) {
  switch (status) {
    case IntegrationStatus::kOk: return "ok";
    case IntegrationStatus::kEmptyBuffer: return "no IMU samples";
    case IntegrationStatus::kNotYetAvailable: return "IMU samples not yet available";
    case IntegrationStatus::kTooOld: return "IMU samples already discarded";
    case IntegrationStatus::kGap: return "gap in IMU samples";
    case IntegrationStatus::kInvalidTime: return "invalid time";
  }
  return "unknown";
}



namespace {

std::string describeInterval(double t0_s, double t1_s) {
  std::ostringstream out;
  out.precision(6);
  out << std::fixed << "[" << t0_s << ", " << t1_s << "] s";
  return out.str();
}

}  // namespace

Eigen::Vector3d rateAt(const ImuSample& before, const ImuSample& after, double t_s,
                       const IntegrationOptions& options) {
  if (options.interpolation == RateInterpolation::kZeroOrderHold) {
    return before.angular_velocity_rad_s - options.gyro_bias_rad_s;
  }
  const double alpha = (t_s - before.stamp_s) / (after.stamp_s - before.stamp_s);
  return (1.0 - alpha) * before.angular_velocity_rad_s + alpha * after.angular_velocity_rad_s -
         options.gyro_bias_rad_s;
}

IntegrationResult checkCoverage(const ImuSampleBuffer& buffer, double t0_s, double t1_s,
                                const IntegrationOptions& options) {
  IntegrationResult result;
  if (!std::isfinite(t0_s) || !std::isfinite(t1_s)) {
    result.status = IntegrationStatus::kInvalidTime;
    result.reason = "non-finite integration time " + describeInterval(t0_s, t1_s);
    return result;
  }
  const double begin = std::min(t0_s, t1_s);
  const double end = std::max(t0_s, t1_s);
  if (buffer.empty()) {
    result.status = IntegrationStatus::kEmptyBuffer;
    result.reason = "no IMU samples buffered for " + describeInterval(begin, end);
    return result;
  }
  std::ostringstream why;
  why.precision(6);
  why << std::fixed;
  if (end > buffer.newestStamp()) {
    why << "IMU samples end at " << buffer.newestStamp() << " s, before the end of "
        << describeInterval(begin, end);
    result.status = IntegrationStatus::kNotYetAvailable;
    result.reason = why.str();
    return result;
  }
  if (begin < buffer.oldestStamp()) {
    why << "IMU samples start at " << buffer.oldestStamp() << " s, after the start of "
        << describeInterval(begin, end);
    result.status = IntegrationStatus::kTooOld;
    result.reason = why.str();
    return result;
  }
  const auto& samples = buffer.samples();
  // First sample strictly after `begin`; the interval containing `begin` starts one before it.
  auto it = std::upper_bound(samples.begin(), samples.end(), begin,
                             [](double t, const ImuSample& s) { return t < s.stamp_s; });
  if (it != samples.begin()) --it;
  for (; it + 1 != samples.end() && it->stamp_s < end; ++it) {
    const double gap = (it + 1)->stamp_s - it->stamp_s;
    if (gap > options.max_sample_gap_s) {
      why << std::setprecision(3) << "IMU gap of " << gap * 1e3 << " ms (limit "
          << options.max_sample_gap_s * 1e3 << " ms) after " << std::setprecision(6) << it->stamp_s << " s inside " << describeInterval(begin, end);
      result.status = IntegrationStatus::kGap;
      result.reason = why.str();
      return result;
    }
  }
  return result;
}

IntegrationResult integrateRotation(const ImuSampleBuffer& buffer, double t0_s, double t1_s,
                                    const IntegrationOptions& options) {
  IntegrationResult result = checkCoverage(buffer, t0_s, t1_s, options);
  if (!result.ok() || t0_s == t1_s) return result;
  const bool reversed = t1_s < t0_s;
  const double begin = reversed ? t1_s : t0_s;
  const double end = reversed ? t0_s : t1_s;

  const auto& samples = buffer.samples();
  auto it = std::upper_bound(samples.begin(), samples.end(), begin,
                             [](double t, const ImuSample& s) { return t < s.stamp_s; });
  if (it != samples.begin()) --it;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  for (; it + 1 != samples.end() && it->stamp_s < end; ++it) {
    const ImuSample& before = *it;
    const ImuSample& after = *(it + 1);
    const double start = std::max(begin, before.stamp_s);
    const double stop = std::min(end, after.stamp_s);
    const double dt = stop - start;
    if (dt <= 0.0) continue;
    const Eigen::Vector3d w_start = rateAt(before, after, start, options);
    Eigen::Vector3d rotation_vector;
    if (options.interpolation == RateInterpolation::kZeroOrderHold) {
      rotation_vector = w_start * dt;
    } else {
      const Eigen::Vector3d w_stop = rateAt(before, after, stop, options);
      rotation_vector = 0.5 * (w_start + w_stop) * dt + (dt * dt / 12.0) * w_start.cross(w_stop);
    }
    // Body-frame rates compose on the right: R(t + dt) = R(t) exp(w dt).
    rotation = rotation * expSO3(rotation_vector);
  }
  result.rotation = reversed ? Eigen::Matrix3d(rotation.transpose()) : rotation;
  return result;
}

}  // namespace deep_ois
