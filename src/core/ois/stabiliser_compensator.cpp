#include "deep_ois/core/ois/stabiliser_compensator.h"

#include <algorithm>
#include <stdexcept>

#include "deep_ois/core/ois/lens_shift_homographies.h"

namespace deep_ois {

std::vector<CameraRateSample> cameraRates(const ImuSampleBuffer& imu,
                                          const Eigen::Matrix3d& imu_to_camera_rotation,
                                          double after_s, double until_s) {
  std::vector<CameraRateSample> rates;
  const auto& samples = imu.samples();
  // Samples are in increasing time: start at the first one after after_s.
  auto it = std::upper_bound(samples.begin(), samples.end(), after_s,
                             [](double t, const ImuSample& sample) { return t < sample.stamp_s; });
  for (; it != samples.end(); ++it) {
    rates.push_back({it->stamp_s, imu_to_camera_rotation * it->angular_velocity_rad_s});
    if (it->stamp_s >= until_s) break;
  }
  return rates;
}

StabiliserCompensator::StabiliserCompensator(const StabiliserModel& parameters,
                                             const Eigen::Matrix3d& K, double warm_up_s)
    : K_(K), warm_up_s_(warm_up_s), predictor_(parameters, K(0, 0)) {
  if (!(warm_up_s >= 0.0)) throw std::invalid_argument("StabiliserCompensator: warm_up_s < 0");
}

double StabiliserCompensator::followTimeline(double frame_a_s, double frame_b_s, double calibration_shift_s) {
  double back_s = 0.0;
  // Consecutive pairs share a frame (the next pair's frame a is the last one's frame b; later
  // after a lost pair). Earlier than that by more than a stamp's rounding is another timeline;
  // an applied calibration moves frame a by its shift without time going anywhere.
  const double expected_at_least_s = last_frame_b_s_ + calibration_shift_s;
  if (seen_pair_ && frame_a_s < expected_at_least_s - 1e-6) {
    back_s = expected_at_least_s - frame_a_s;
    predictor_.reset();
    ++time_jumps_;
  } else if (seen_pair_ && calibration_shift_s != 0.0) {
    ++calibration_changes_;
    // Moved back: the model answers from its retained history (a few hundred ms), not beyond.
    if (predictor_.started() && frame_a_s < predictor_.newestStamp() && !predictor_.covers(frame_a_s)) {
      predictor_.reset();
      ++calibration_restarts_;
    }
  }
  seen_pair_ = true;
  last_frame_b_s_ = frame_b_s;
  return back_s;
}

void StabiliserCompensator::addRates(const std::vector<CameraRateSample>& rates) {
  // Consecutive pairs repeat up to a second of gyro history, so older samples are skipped here
  // and the predictor's own jump-back reset (for a single stream) never sees a bag loop: that is
  // what followTimeline() detects, at the pair level.
  for (const CameraRateSample& sample : rates) {
    if (predictor_.started() && sample.stamp_s <= predictor_.newestStamp()) continue;
    predictor_.addRate(sample);
  }
}

double StabiliserCompensator::feedFrom(double t_first_s) const {
  return predictor_.started() ? predictor_.newestStamp() : t_first_s - warm_up_s_;
}

StabiliserCompensation StabiliserCompensator::compensate(
    const std::vector<Eigen::Matrix3d>& rotations, const std::vector<double>& patch_times_a_s,
    const std::vector<double>& patch_times_b_s) const {
  StabiliserCompensation result;
  if (patch_times_a_s.size() != rotations.size() || patch_times_b_s.size() != rotations.size()) {
    result.reason = "one patch time per rotation and frame needed";
    return result;
  }
  for (std::size_t i = 0; i < rotations.size(); ++i) {
    if (!predictor_.covers(patch_times_a_s[i]) || !predictor_.covers(patch_times_b_s[i])) {
      result.reason = "the stabiliser model's gyro stream does not cover the pair";
      return result;
    }
    result.shift_a_px.push_back(predictor_.lensShiftAt(patch_times_a_s[i]));
    result.shift_b_px.push_back(predictor_.lensShiftAt(patch_times_b_s[i]));
  }
  result.homographies = lensShiftHomographies(K_, rotations, result.shift_a_px, result.shift_b_px);
  result.ok = true;
  return result;
}

}  // namespace deep_ois
