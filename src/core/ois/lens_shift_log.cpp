#include "deep_ois/core/ois/lens_shift_log.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

Eigen::Matrix2d LensShiftLogConvention::matrix() const {
  Eigen::Matrix2d P =
      swap_xy ? (Eigen::Matrix2d() << 0, 1, 1, 0).finished() : Eigen::Matrix2d::Identity();
  P.row(0) *= sign_x;
  P.row(1) *= sign_y;
  return scale * P;
}

Eigen::Vector2d LensShiftLogConvention::toImagePx(const Eigen::Vector2d& logged) const {
  return matrix() * logged;
}

std::string LensShiftLogConvention::validate() const {
  if (!std::isfinite(scale) || scale <= 0.0)
    return "scale must be a positive number of pixels per logged unit";
  if (sign_x != 1.0 && sign_x != -1.0) return "sign_x must be +1 or -1";
  if (sign_y != 1.0 && sign_y != -1.0) return "sign_y must be +1 or -1";
  if (!std::isfinite(time_offset_s) || std::abs(time_offset_s) > 10.0) {
    return "time_offset must be within +-10 s";
  }
  return {};
}

LensShiftLog::LensShiftLog(double max_gap_s, const LensShiftLogConvention& convention)
    : max_gap_s_(max_gap_s) {
  if (!std::isfinite(max_gap_s) || max_gap_s <= 0.0) {
    throw std::invalid_argument("LensShiftLog: max_gap must be a positive number of seconds");
  }
  setConvention(convention);
}

void LensShiftLog::setConvention(const LensShiftLogConvention& convention) {
  const std::string problem = convention.validate();
  if (!problem.empty()) throw std::invalid_argument("lens shift log convention: " + problem);
  convention_ = convention;
}

LensShiftAddResult LensShiftLog::add(const LensShiftLogSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.logged.allFinite())
    return {"non-finite stamp or shift"};
  if (sample.covariance && !sample.covariance->allFinite()) return {"non-finite covariance"};
  if (!samples_.empty() && !(sample.stamp_s > samples_.back().stamp_s)) {
    std::ostringstream why;
    why.precision(9);
    why << (sample.stamp_s == samples_.back().stamp_s ? "duplicate" : "out-of-order") << " stamp "
        << sample.stamp_s << " s (newest " << samples_.back().stamp_s << " s)";
    return {why.str()};
  }
  samples_.push_back(sample);
  return {};
}

std::ptrdiff_t LensShiftLog::lastAtOrBefore(double t_s) const {
  const auto after =
      std::upper_bound(samples_.begin(), samples_.end(), t_s,
                       [this](double t, const LensShiftLogSample& s) { return t < cameraTime(s); });
  return (after - samples_.begin()) - 1;
}

bool LensShiftLog::covers(double t0_s, double t1_s) const {
  if (samples_.empty() || !(t0_s <= t1_s) || !std::isfinite(t0_s) || !std::isfinite(t1_s))
    return false;
  const std::ptrdiff_t first = lastAtOrBefore(t0_s);
  if (first < 0) return false;
  // Every interval from the sample at or before t0 to the first sample at or after t1.
  std::size_t i = static_cast<std::size_t>(first);
  if (cameraTime(samples_[i]) == t1_s) return true;
  for (; i + 1 < samples_.size(); ++i) {
    if (cameraTime(samples_[i + 1]) - cameraTime(samples_[i]) > max_gap_s_) return false;
    if (cameraTime(samples_[i + 1]) >= t1_s) return true;
  }
  return false;  // the log ends before t1
}

Eigen::Vector2d LensShiftLog::shiftAt(double t_s) const {
  if (!covers(t_s, t_s)) {
    std::ostringstream why;
    why.precision(9);
    why << "LensShiftLog::shiftAt: " << t_s << " s is not covered by the log (";
    if (samples_.empty()) {
      why << "empty)";
    } else {
      why << oldestStampS() << " .. " << newestStampS() << " s, max gap " << max_gap_s_ << " s)";
    }
    throw std::out_of_range(why.str());
  }
  const std::size_t i = static_cast<std::size_t>(lastAtOrBefore(t_s));
  const LensShiftLogSample& a = samples_[i];
  if (cameraTime(a) == t_s || i + 1 >= samples_.size()) return convention_.toImagePx(a.logged);
  const LensShiftLogSample& b = samples_[i + 1];
  const double w = (t_s - cameraTime(a)) / (cameraTime(b) - cameraTime(a));
  return convention_.toImagePx((1.0 - w) * a.logged + w * b.logged);
}

double LensShiftLog::newestStampS() const {
  return samples_.empty() ? -std::numeric_limits<double>::infinity() : cameraTime(samples_.back());
}

double LensShiftLog::oldestStampS() const {
  return samples_.empty() ? std::numeric_limits<double>::infinity() : cameraTime(samples_.front());
}

void LensShiftLog::dropBefore(double t_s) {
  const std::ptrdiff_t keep = lastAtOrBefore(t_s);
  if (keep > 0) samples_.erase(samples_.begin(), samples_.begin() + keep);
}

}  // namespace deep_ois
