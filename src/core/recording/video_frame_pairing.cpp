#include "deep_ois/core/recording/video_frame_pairing.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <sstream>

namespace deep_ois {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const Eigen::Vector2d kNaN2(kNaN, kNaN);

// R^2 of `image` explained by A * `gyro` + b, A (2x2) and b fitted by least squares over the pairs
// where both are finite; `count` gets their number.
double explainedShare(const std::vector<Eigen::Vector2d>& image, const std::vector<Eigen::Vector2d>& gyro, int& count) {
  // Only where the camera turns (the gyro's motion above its median): while it is still, what moves
  // in the image is the scene (a person in front of a phone on a table), not the camera.
  std::vector<double> magnitudes;
  for (const Eigen::Vector2d& g : gyro)
    if (g.allFinite()) magnitudes.push_back(g.norm());
  if (magnitudes.size() < 16) return kNaN;
  std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<long>(magnitudes.size() / 2), magnitudes.end());
  const double threshold = magnitudes[magnitudes.size() / 2];
  std::vector<std::size_t> used;
  for (std::size_t k = 0; k < image.size() && k < gyro.size(); ++k)
    if (image[k].allFinite() && gyro[k].allFinite() && gyro[k].norm() > threshold) used.push_back(k);
  count = static_cast<int>(used.size());
  if (count < 8) return kNaN;
  Eigen::MatrixXd X(count, 3), Y(count, 2);
  for (int i = 0; i < count; ++i) {
    X.row(i) << gyro[used[i]].x(), gyro[used[i]].y(), 1.0;
    Y.row(i) = image[used[i]].transpose();
  }
  const Eigen::MatrixXd coefficients = X.colPivHouseholderQr().solve(Y);
  const double residual = (Y - X * coefficients).squaredNorm();
  const double total = (Y.rowwise() - Y.colwise().mean()).squaredNorm();
  return total > 0 ? 1.0 - residual / total : kNaN;
}

// The rows' series seen from the video frames at `shift`: element j is row j - shift.
std::vector<Eigen::Vector2d> shifted(const std::vector<Eigen::Vector2d>& rows, std::size_t frames, int shift) {
  std::vector<Eigen::Vector2d> out(frames, kNaN2);
  for (std::size_t j = 0; j < frames; ++j) {
    const long r = static_cast<long>(j) - shift;
    if (r >= 0 && r < static_cast<long>(rows.size())) out[j] = rows[static_cast<std::size_t>(r)];
  }
  return out;
}

std::vector<double> shiftedScalars(const std::vector<double>& rows, std::size_t frames, int shift) {
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

Eigen::Vector2d ConsecutiveImageMotion::add(const cv::Mat& grey) {
  const cv::Mat current = grey.clone();
  Eigen::Vector2d motion = kNaN2;
  if (!previous_.empty() && previous_.size() == current.size()) {
    // Tracks and a RANSAC similarity: the motion of the larger rigid part of the image (the
    // background), not of a person moving in front of it (which a phase correlation follows).
    std::vector<cv::Point2f> corners, tracked;
    cv::goodFeaturesToTrack(previous_, corners, 300, 0.01, 6.0);
    if (corners.size() >= 12) {
      std::vector<unsigned char> found;
      std::vector<float> errors;
      cv::calcOpticalFlowPyrLK(previous_, current, corners, tracked, found, errors, cv::Size(15, 15), 3);
      std::vector<cv::Point2f> a, b;
      for (std::size_t i = 0; i < corners.size(); ++i)
        if (found[i]) a.push_back(corners[i]), b.push_back(tracked[i]);
      if (a.size() >= 12) {
        std::vector<unsigned char> inliers;
        const cv::Mat similarity = cv::estimateAffinePartial2D(a, b, inliers, cv::RANSAC, 1.0);
        if (!similarity.empty() && cv::countNonZero(inliers) >= 10) {
          // The motion of the image centre.
          const double cx = 0.5 * (current.cols - 1), cy = 0.5 * (current.rows - 1);
          const double x = similarity.at<double>(0, 0) * cx + similarity.at<double>(0, 1) * cy + similarity.at<double>(0, 2);
          const double y = similarity.at<double>(1, 0) * cx + similarity.at<double>(1, 1) * cy + similarity.at<double>(1, 2);
          motion = Eigen::Vector2d(x - cx, y - cy);
        }
      }
    }
  }
  previous_ = current;
  motions_px_.push_back(motion);
  return motion;
}

std::vector<Eigen::Vector2d> gyroImageMotionPx(const std::vector<ImuSample>& gyro, const std::vector<double>& stamps_s,
                                               const Eigen::Matrix3d& imu_to_camera_rotation, double focal_px) {
  std::vector<Eigen::Vector2d> out(stamps_s.size(), kNaN2);
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
    out[k] = focal_px * Eigen::Vector2d(camera.x(), camera.y());
  }
  return out;
}

VideoFramePairing pairVideoFrames(const std::vector<double>& presentation_s,
                                  const std::vector<Eigen::Vector2d>& image_motion_px,
                                  const std::vector<double>& row_stamps_s,
                                  const std::vector<Eigen::Vector2d>& gyro_motion_px, int max_shift) {
  VideoFramePairing pairing;
  const std::size_t frames = image_motion_px.size();
  // Do the presentation times carry timing? A re-encode writes a uniform 1/fps.
  // The last frame's position is not always reported: only the frames before it count.
  std::vector<double> pts_intervals = intervals(presentation_s);
  if (!pts_intervals.empty()) pts_intervals.back() = kNaN;
  std::vector<double> finite;
  int not_increasing = 0;
  for (double d : pts_intervals) {
    if (!std::isfinite(d)) continue;
    finite.push_back(d);
    not_increasing += !(d > 0.0);
  }
  std::sort(finite.begin(), finite.end());
  const double lo = finite.empty() ? 0.0 : finite[finite.size() / 20];
  const double hi = finite.empty() ? 0.0 : finite[finite.size() - 1 - finite.size() / 20];
  const bool timing = finite.size() > 2 && not_increasing == 0 && hi - lo > 1e-3;
  std::ostringstream note;
  note << std::fixed << std::setprecision(2);
  if (finite.size() > 2) {
    note << "presentation-time intervals " << lo * 1e3 << " .. " << hi * 1e3 << " ms (5-95 %)";
    if (not_increasing > 0) note << ", " << not_increasing << " not increasing (unusable; paired by order)";
    else note << (timing ? " (they carry timing: matched to the rows' intervals)" : " (uniform: no timing; paired by order)");
  }
  pairing.timing_note = note.str();
  int best_timing_shift = 0;
  if (timing) {
    const std::vector<double> row_intervals = intervals(row_stamps_s);
    double best = std::numeric_limits<double>::infinity();
    for (int shift = -max_shift; shift <= max_shift; ++shift) {
      const std::vector<double> rows = shiftedScalars(row_intervals, presentation_s.size(), shift);
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
    const double c = explainedShare(image_motion_px, shifted(gyro_motion_px, frames, shift), count);
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
    const double c = explainedShare(image_motion_px, shifted(gyro_motion_px, frames, pairing.shift), count);
    pairing.correlation = std::isfinite(c) ? c : 0.0;
    pairing.compared = count;
  }
  if (timing && pairing.shift != best_shift) second = best, second_shift = best_shift;
  (void)best_count;
  pairing.runner_up_shift = second_shift;
  pairing.runner_up_correlation = second > -2 ? second : 0.0;
  // Gaussian log-likelihood ratio of the two fits over the same intervals: n/2 * ln(SSR_2 / SSR_1)
  // (the intervals are not fully independent, so it is a heuristic; 5 means e^5 ~ 150 : 1).
  pairing.log_likelihood_ratio =
      0.5 * pairing.compared *
      std::log(std::max(1.0 - pairing.runner_up_correlation, 1e-9) / std::max(1.0 - pairing.correlation, 1e-9));
  pairing.confident = pairing.correlation >= 0.2 && pairing.log_likelihood_ratio >= 5.0 &&
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
  out << "; image motion explained by the gyro R^2 " << correlation << " over " << compared
      << " frame intervals where the camera turns (next best: shift " << runner_up_shift << ", " << runner_up_correlation
      << "; log-likelihood ratio " << std::setprecision(1) << log_likelihood_ratio << std::setprecision(2) << "); confidence "
      << (confident ? "high" : "LOW") << "; " << video_frames_without_row << " video frames without a row, "
      << rows_without_frame << " rows without a frame";
  if (!timing_note.empty()) out << "; " << timing_note;
  return out.str();
}

}  // namespace deep_ois
