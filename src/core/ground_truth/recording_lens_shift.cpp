#include "deep_ois/core/ground_truth/recording_lens_shift.h"

#include <stdexcept>
#include <string>

namespace deep_ois {

RecordingLensShift estimateRecordingLensShift(const CameraModel& camera, const std::vector<cv::Mat>& gray_frames,
                                              const std::vector<double>& frame_stamps_s,
                                              const ImuSampleBuffer& imu, const IntegrationOptions& integration,
                                              const RollingShutterConfig& rolling_shutter,
                                              LensShiftOptions options, const FeatureTracker& tracker) {
  if (gray_frames.size() != frame_stamps_s.size()) {
    throw std::invalid_argument("estimateRecordingLensShift: " + std::to_string(gray_frames.size()) +
                                " frames but " + std::to_string(frame_stamps_s.size()) + " stamps");
  }
  RecordingLensShift out;
  for (std::size_t f = 0; f + 1 < gray_frames.size(); ++f) {
    const RollingShutterHomographies gyro = computeRollingShutterHomographies(
        imu, integration, rolling_shutter, camera.K(), frame_stamps_s[f], frame_stamps_s[f + 1]);
    if (!gyro.ok()) {
      ++out.pairs_without_gyro;
      continue;
    }
    LensShiftPairObservation pair;
    pair.frame_a = static_cast<int>(f);
    pair.frame_b = static_cast<int>(f + 1);
    pair.rotations = gyro.rotations;
    pair.matches = tracker.match(gray_frames[f], gray_frames[f + 1]);
    out.pairs.push_back(std::move(pair));
    out.gyro_homographies.push_back(gyro.homographies);
  }
  if (out.pairs.empty()) return out;
  options.patch_count = rolling_shutter.patch_count;
  options.readout_time_s = rolling_shutter.readout_time_s;
  out.trajectory = estimateLensShiftTrajectory(camera, frame_stamps_s, out.pairs, options);
  return out;
}

}  // namespace deep_ois
