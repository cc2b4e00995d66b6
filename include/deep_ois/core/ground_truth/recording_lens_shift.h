// The gyro-anchored lens trajectory of a whole recording (lens_shift_ground_truth.h) from its
// frames and IMU stream: consecutive frames paired, each pair's camera rotation per row patch from
// the gyro with the gyro flow nodelet's code and rolling-shutter parameters, point tracks from the
// offline job's tracker. One path for train_stabiliser's images target and the
// evaluate_lens_shift_ground_truth tool.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <opencv2/core.hpp>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

struct RecordingLensShift {
  // The consecutive frame pairs the gyro covers, in order, with their rotations and tracks.
  std::vector<LensShiftPairObservation> pairs;
  // Per pair: the gyro's homographies K R K^-1 per row patch (the uncompensated prediction).
  std::vector<std::vector<Eigen::Matrix3d>> gyro_homographies;
  std::size_t pairs_without_gyro = 0;  // consecutive pairs the IMU does not cover
  // Empty (no shift_px) when no pair is covered.
  LensShiftTrajectory trajectory;
};

// `gray_frames[f]` was captured at `frame_stamps_s[f]` (seconds on the IMU buffer's time base,
// increasing). The options' patch count and readout are taken from `rolling_shutter`. Throws
// std::invalid_argument as estimateLensShiftTrajectory does, or when the two vectors differ in size.
RecordingLensShift estimateRecordingLensShift(const CameraModel& camera, const std::vector<cv::Mat>& gray_frames,
                                              const std::vector<double>& frame_stamps_s,
                                              const ImuSampleBuffer& imu, const IntegrationOptions& integration,
                                              const RollingShutterConfig& rolling_shutter,
                                              LensShiftOptions options, const FeatureTracker& tracker);

}  // namespace deep_ois
