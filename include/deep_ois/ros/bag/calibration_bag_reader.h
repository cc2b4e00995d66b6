// Builds the camera-IMU calibration's input from a rosbag: the gyro stream, the frame stamps,
// camera_info and the KLT tracks of every consecutive frame pair (the Fundamental Mixtures
// tracker: uniform FAST corners, pyramidal KLT with a forward-backward check).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/common/progress_callback.h"
#include "deep_ois/ros/bag/bag_sequence.h"

namespace deep_ois {

struct CalibrationBagOptions {
  BagSequenceTopics topics;
  CornerDetectorOptions corners;
  KltOptions klt = calibrationKltOptions();  // an 11 px window (see there)
  // Frame pairs further apart than this are not tracked (frames dropped upstream), seconds.
  double max_frame_interval_s = 0.25;
};

struct CalibrationBag {
  CalibrationData data;  // stamps in seconds since the bag's time base (IMU and frames alike)
  std::string imu_frame_id;
  std::string camera_frame_id;
  // R_cam_imu from the bag's /tf_static, when it has one (for comparison or to hold it).
  std::optional<Eigen::Matrix3d> tf_imu_to_camera_rotation;
  std::string tf_problem;  // why tf_imu_to_camera_rotation is empty (BagSequence::imu_to_camera_problem)
  // Ground truth of a simulator bag: whether its OIS was on (empty for a real recording).
  std::optional<bool> simulated_ois_enabled;
  // The camera's lens-shift log (topics.lens_shift_log) as logged, stamps on the bag's time base;
  // empty when the bag has none.
  std::vector<LensShiftLogSample> lens_shift_log;
  std::size_t frames = 0;
  double tracking_seconds = 0.0;  // wall time of corner detection + KLT
};

// Reads the bag once for IMU/camera_info/tf (readBagSequence) and streams its frames once for the
// tracks. Throws std::runtime_error naming the bag and the problem (unreadable, no camera_info,
// a frame whose size differs from camera_info, fewer than two frames). `on_progress`, when given,
// is called with (frame pairs read, frame pairs in the bag's index).
CalibrationBag readCalibrationBag(const std::string& path, const CalibrationBagOptions& options,
                                  const ProgressCallback& on_progress = {});


}  // namespace deep_ois
