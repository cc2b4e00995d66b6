#include "deep_ois/core/recording/video_frame_pairing.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace deep_ois {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Pearson correlation of the pairs where both are finite; `count` gets their number.
double correlation(const std::vector<double>& a, const std::vector<double>& b, int& count) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  count = 0;
  for (std::size_t k = 0; k < a.size() && k < b.size(); ++k) {
    if (!std::isfinite(a[k]) || !std::isfinite(b[k])) continue;
    sa += a[k], sb += b[k], saa += a[k] * a[k], sbb += b[k] * b[k], sab += a[k] * b[k];
    ++count;
  }
  if (count < 3) return kNaN;
  const double n = count;
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  if (va <= 0 || vb <= 0) return kNaN;
  return (sab - sa * sb / n) / std::sqrt(va * vb);
}

// The rows' series seen from the video frames at `shift`: element j is row j - shift.
std::vector<double> shifted(const std::vector<double>& rows, std::size_t frames, int shift) {
  std::vector<double> out(frames, kNaN);
  for (std::size_t j = 0; j < frames; ++j) {
    const long r = static_cast<long>(j) - shift;
    if (r >= 0 && r < static_cast<long>(rows.size())) out[j] = rows[static_cast<std::size_t>(r)];
  }
  return out;
}

std::vector<double> intervals(const std::vector<double>& stamps) {
  std::vector<double> out(stamps.size(), kNaN);
  for (std::size_t k = 1; k < stamps.size(); ++k) out[k] = stamps[k] - stamps[k - 1];
  return out;
}

}  // namespace

double ConsecutiveImageMotion::add(const cv::Mat& grey) {
  cv::Mat current;
  grey.convertTo(current, CV_32F);
  double motion = kNaN;
  if (!previous_.empty() && previous_.size() == current.size()) {
    if (window_.size() != current.size()) cv::createHanningWindow(window_, current.size(), CV_32F);
    const cv::Point2d shift = cv::phaseCorrelate(previous_, current, window_);
    motion = std::hypot(shift.x, shift.y);
  }
  previous_ = current;
  motions_px_.push_back(motion);
  return motion;
}

std::vector<double> gyroImageMotionPx(const std::vector<ImuSample>& gyro, const std::vector<double>& stamps_s,
                                      const Eigen::Matrix3d& imu_to_camera_rotation, double focal_px) {
  std::vector<double> out(stamps_s.size(), kNaN);
  if (gyro.size() < 2) return out;
  // Rate at time t, linear between samples.
  auto rateAt = [&](double t, std::size_t& hint) -> Eigen::Vector3d {
    while (hint + 1 < gyro.size() && gyro[hint + 1].stamp_s < t) ++hint;
    const ImuSample& a = gyro[hint];
    const ImuSample& b = gyro[std::min(hint + 1, gyro.size() - 1)];
    const double span = b.stamp_s - a.stamp_s;
    const double w = span > 0 ? std::clamp((t - a.stamp_s) / span, 0.0, 1.0) : 0.0;
    return (1 - w) * a.angular_velocity_rad_s + w * b.angular_velocity_rad_s;
  };
  std::size_t hint = 0;
  for (std::size_t k = 1; k < stamps_s.size(); ++k) {
    const double t0 = stamps_s[k - 1], t1 = stamps_s[k];
    if (t0 < gyro.front().stamp_s || t1 > gyro.back().stamp_s || !(t1 > t0)) continue;
    constexpr int kSteps = 16;  // trapezoid steps per interval: ~2 ms at 30 fps
    Eigen::Vector3d angle = Eigen::Vector3d::Zero();
    const double dt = (t1 - t0) / kSteps;
    std::size_t h = hint;
    Eigen::Vector3d previous = rateAt(t0, h);
    for (int s = 1; s <= kSteps; ++s) {
      const Eigen::Vector3d rate = rateAt(t0 + s * dt, h);
      angle += 0.5 * (previous + rate) * dt;
      previous = rate;
    }
    while (hint + 1 < gyro.size() && gyro[hint + 1].stamp_s < t0) ++hint;
    const Eigen::Vector3d camera = imu_to_camera_rotation * angle;
    out[k] = focal_px * std::hypot(camera.x(), camera.y());
  }
  return out;
}

VideoFramePairing pairVideoFrames(const std::vector<double>& presentation_s, const std::vector<double>& image_motion_px,
                                  const std::vector<double>& row_stamps_s, const std::vector<double>& gyro_motion_px,
                                  int max_shift) {
  VideoFramePairing pairing;
  const std::size_t frames = image_motion_px.size();
  // Do the presentation times carry timing? A re-encode writes a uniform 1/fps.
  const std::vector<double> pts_intervals = intervals(presentation_s);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double d : pts_intervals)
    if (std::isfinite(d)) lo = std::min(lo, d), hi = std::max(hi, d);
  const bool timing = presentation_s.size() > 2 && hi - lo > 1e-3;
  std::ostringstream note;
  note << std::fixed << std::setprecision(2);
  if (presentation_s.size() > 2) {
    note << "presentation-time intervals " << lo * 1e3 << " .. " << hi * 1e3 << " ms"
         << (timing ? " (they carry timing: matched to the rows' intervals)" : " (uniform: no timing; paired by order)");
  }
  pairing.timing_note = note.str();
  int best_timing_shift = 0;
  if (timing) {
    const std::vector<double> row_intervals = intervals(row_stamps_s);
    double best = std::numeric_limits<double>::infinity();
    for (int shift = -max_shift; shift <= max_shift; ++shift) {
      const std::vector<double> rows = shifted(row_intervals, presentation_s.size(), shift);
      std::vector<double> errors;
      for (std::size_t j = 0; j < rows.size(); ++j)
        if (std::isfinite(rows[j]) && std::isfinite(pts_intervals[j])) errors.push_back(std::abs(rows[j] - pts_intervals[j]));
      if (errors.size() < 3) continue;
      std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() / 2), errors.end());
      if (errors[errors.size() / 2] < best) best = errors[errors.size() / 2], best_timing_shift = shift;
    }
  }
  double best = -2, second = -2;
  int best_shift = 0, second_shift = 0, best_count = 0;
  for (int shift = -max_shift; shift <= max_shift; ++shift) {
    int count = 0;
    const double c = correlation(image_motion_px, shifted(gyro_motion_px, frames, shift), count);
    if (!std::isfinite(c)) continue;
    if (c > best) {
      second = best, second_shift = best_shift;
      best = c, best_shift = shift, best_count = count;
    } else if (c > second) {
      second = c, second_shift = shift;
    }
  }
  pairing.by_presentation_time = timing;
  pairing.shift = timing ? best_timing_shift : best_shift;
  {
    int count = 0;
    const double c = correlation(image_motion_px, shifted(gyro_motion_px, frames, pairing.shift), count);
    pairing.correlation = std::isfinite(c) ? c : 0.0;
    pairing.compared = count;
  }
  if (timing && pairing.shift != best_shift) second = best, second_shift = best_shift;
  (void)best_count;
  pairing.runner_up_shift = second_shift;
  pairing.runner_up_correlation = second > -2 ? second : 0.0;
  pairing.confident = pairing.correlation >= 0.6 && pairing.correlation - pairing.runner_up_correlation >= 0.2 &&
                      (!timing || pairing.shift == best_shift);
  for (std::size_t j = 0; j < frames; ++j) {
    const long r = static_cast<long>(j) - pairing.shift;
    pairing.video_frames_without_row += r < 0 || r >= static_cast<long>(row_stamps_s.size());
  }
  pairing.rows_without_frame =
      static_cast<int>(row_stamps_s.size()) - (static_cast<int>(frames) - pairing.video_frames_without_row);
  return pairing;
}

std::string VideoFramePairing::summary() const {
  std::ostringstream out;
  out << std::fixed << std::setprecision(2);
  out << "frame pairing: video frame j = metadata row j" << (shift >= 0 ? " - " : " + ") << std::abs(shift);
  if (shift != 0) out << " (a shift of " << std::abs(shift) << " whole frame" << (std::abs(shift) == 1 ? "" : "s") << ")";
  out << "; image motion vs gyro correlation " << correlation << " over " << compared
      << " frame intervals (next best: shift " << runner_up_shift << ", " << runner_up_correlation << "); confidence "
      << (confident ? "high" : "LOW") << "; " << video_frames_without_row << " video frames without a row, "
      << rows_without_frame << " rows without a frame";
  if (!timing_note.empty()) out << "; " << timing_note;
  return out.str();
}

}  // namespace deep_ois
