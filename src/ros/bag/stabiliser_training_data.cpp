#include "deep_ois/ros/bag/stabiliser_training_data.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <map>
#include <stdexcept>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/ground_truth/lens_motion_observations.h"
#include "deep_ois/core/ground_truth/recording_lens_shift.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
LensMotionTarget lensMotionTargetOf(const std::string& bag_path) {
  const BagSequenceTopics topics;  // the topics readStabiliserRecording reads
  try {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    if (rosbag::View(bag, rosbag::TopicQuery(topics.frame_pair_truth)).size() > 0)
      return LensMotionTarget::kSimulatorTruth;
    if (rosbag::View(bag, rosbag::TopicQuery(topics.lens_shift_log)).size() > 0)
      return LensMotionTarget::kLensLog;
  } catch (const std::exception& e) {
    throw std::runtime_error(bag_path + ": " + e.what());
  }
  return LensMotionTarget::kImages;
}

StabiliserRecordingData readStabiliserRecording(const std::string& bag_path,
                                                const GyroFlowParameters& gyro,
                                                LensMotionTarget target,
                                                const LensShiftOptions& lens_options) {
  std::vector<BagFrame> frames;
  const bool images = target == LensMotionTarget::kImages;
  const BagSequence bag =
      readBagSequence(bag_path, {}, BagReadFailure::kThrow, images ? &frames : nullptr);
  auto fail = [&](const std::string& what) { throw std::runtime_error(bag_path + ": " + what); };
  if (!bag.imu_problem.empty()) fail(bag.imu_problem);
  const CameraModel& camera = *bag.camera;
  RollingShutterConfig rs = gyro.rolling_shutter;
  if (gyro.rotation_from_tf) {
    if (!bag.imu_to_camera_rotation) fail(bag.imu_to_camera_problem);
    rs.imu_to_camera_rotation = *bag.imu_to_camera_rotation;
  }
  const ImuSampleBuffer imu = bag.imuBuffer();

  StabiliserRecordingData data;
  StabiliserFitRecording& recording = data.recording;
  recording.name = bag_path;
  recording.focal_px = camera.K()(0, 0);
  for (const ImuSample& sample : imu.samples())
    recording.rates.push_back({sample.stamp_s, rs.imu_to_camera_rotation * sample.angular_velocity_rad_s});

  std::vector<double> stamps_s;
  // The frames' own stamps when the images are read (their order is the pairs'), else camera_info's.
  if (images) {
    for (const BagFrame& frame : frames) stamps_s.push_back(bag.secondsSinceBase(frame.stamp));
  } else {
    for (const ros::Time& stamp : bag.frame_stamps) stamps_s.push_back(bag.secondsSinceBase(stamp));
  }
  CameraDescription& description = data.camera;
  description = describeCamera(camera, rs.readout_time_s);
  description.frame_rate_hz = frameRateOfStampsHz(stamps_s);
  if (!bag.truths.empty()) data.recorded_readout_time_s = bag.truths.front().readout_time;

  auto addPair = [&](double stamp_a_s, double stamp_b_s, const std::vector<Eigen::Vector2d>& s_a,
                     const std::vector<Eigen::Vector2d>& s_b) {
    for (int i = 0; i < rs.patch_count; ++i) {
      LensMotionObservation o;
      o.t_a_s = patchImuTime(rs, stamp_a_s, i);
      o.t_b_s = patchImuTime(rs, stamp_b_s, i);
      o.motion_px = s_b[static_cast<std::size_t>(i)] - s_a[static_cast<std::size_t>(i)];
      o.readout_fraction =
          (i + (rs.patch_time == PatchTimeReference::kPatchCentre ? 0.5 : 0.0)) / rs.patch_count;
      recording.observations.push_back(o);
    }
  };

  if (target == LensMotionTarget::kLensLog) {
    if (bag.lens_shift_log.empty()) fail("no lens-shift log in the bag (topic /camera/lens_shift)");
    LensShiftLog log(gyro.lens_shift_max_gap_s, gyro.lens_shift_convention);
    for (const LensShiftLogSample& sample : bag.lens_shift_log) log.add(sample);
    for (std::size_t f = 0; f + 1 < stamps_s.size(); ++f) {
      ++data.frame_pairs;
      // The log is on the camera's clock; the model's times are the IMU's (patchImuTime).
      const double first = patchCameraTime(rs, stamps_s[f], 0);
      const double last = patchCameraTime(rs, stamps_s[f + 1], rs.patch_count - 1);
      if (!log.covers(first, last)) {
        ++data.pairs_without_log;
        continue;
      }
      std::vector<Eigen::Vector2d> s_a, s_b;
      for (int i = 0; i < rs.patch_count; ++i) {
        s_a.push_back(log.shiftAt(patchCameraTime(rs, stamps_s[f], i)));
        s_b.push_back(log.shiftAt(patchCameraTime(rs, stamps_s[f + 1], i)));
      }
      addPair(stamps_s[f], stamps_s[f + 1], s_a, s_b);
    }
    return data;
  }
  if (!images) {
    if (bag.truths.empty())
      fail("no simulator truth on /ground_truth/frame_pair (a simulated recording has it; for a real "
           "one use its lens-shift log, --target log, or the images, --target images)");
    for (const FramePairTruth& truth : bag.truths) {
      if (!truth.ois_enabled) continue;
      ++data.frame_pairs;
      const auto s_a = unflattenPoints(truth.lens_shift_a);
      const auto s_b = unflattenPoints(truth.lens_shift_b);
      if (static_cast<int>(s_a.size()) != rs.patch_count ||
          static_cast<int>(s_b.size()) != rs.patch_count) {
        fail("the truth has " + std::to_string(s_a.size()) + " patches, the gyro flow config " +
             std::to_string(rs.patch_count));
      }
      addPair(bag.secondsSinceBase(truth.previous_stamp), bag.secondsSinceBase(truth.header.stamp),
              s_a, s_b);
    }
    return data;
  }

  // The images: tracks of consecutive frames, the gyro's rotations, one lens trajectory.
  std::vector<cv::Mat> gray;
  for (const BagFrame& frame : frames) gray.push_back(frame.gray);
  const FeatureTracker tracker;  // the offline job's defaults
  const RecordingLensShift estimate =
      estimateRecordingLensShift(camera, gray, stamps_s, imu, gyro.integration, rs, lens_options, tracker);
  data.frame_pairs += frames.size() > 1 ? frames.size() - 1 : 0;
  data.pairs_without_gyro = estimate.pairs_without_gyro;
  if (estimate.pairs.empty()) fail("no frame pair covered by the gyro");
  TrajectoryLensMotions motions =
      lensMotionsOfTrajectory(estimate.pairs, estimate.trajectory, stamps_s, rs);
  data.pairs_without_tracks = motions.pairs_without_tracks;
  recording.observations = std::move(motions.observations);
  const std::vector<double>& residuals = motions.median_track_residual_px;
  if (!residuals.empty()) data.median_track_residual_px = median(residuals);
  return data;
}

}  // namespace deep_ois
