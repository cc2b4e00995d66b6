// Reads one recording (rosbag) into what the stabiliser fit needs (core/ois/stabiliser_fit.h): the
// gyro stream in the camera frame and the lens motion per frame pair and row patch, from
//  - the images: the gyro-anchored lens-shift ground truth (core/ground_truth/
//    lens_shift_ground_truth.h) on the offline job's point tracks, for any recording; or
//  - the camera's own lens-shift log (docs/lens_shift_logs.md), read with the gyro flow
//    parameters' log convention: a phone that logs its lens in a development mode trains the model
//    for units that do not;
//  - the simulator's truth (FramePairTruth lens shifts), to measure what the images lose.
// The gyro side is the gyro flow nodelet's code with its parameters, so a model fitted here sees
// the rotations and patch times the live chain gives it.
#pragma once

#include <cstddef>
#include <string>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"

namespace deep_ois {

// LensMotionTarget (core/ois/stabiliser_fit.h) says which of the three is read.

struct StabiliserRecordingData {
  StabiliserFitRecording recording;
  CameraDescription camera;
  std::size_t frame_pairs = 0;          // consecutive frame pairs in the bag
  std::size_t pairs_without_gyro = 0;   // not covered by the gyro (no observation)
  std::size_t pairs_without_tracks = 0; // too few inlier tracks for the images' estimate
  std::size_t pairs_without_log = 0;    // kLensLog: the log does not cover the pair (a gap)
  double median_track_residual_px = 0.0;  // of the images' estimate (0 for the simulator truth)
  // The readout time the recording itself states (the simulator's truth carries the camera's),
  // seconds; kNotRecorded when it states none. Compared with the gyro config's readout.
  static constexpr double kNotRecorded = -1.0;
  double recorded_readout_time_s = kNotRecorded;
};

// The lens motion `bag_path` can give, from its index alone (no message read): the simulator's
// truth when it has it (a simulated recording), else the camera's lens-shift log, else the images.
// Throws std::runtime_error naming the bag when it cannot be opened.
LensMotionTarget lensMotionTargetOf(const std::string& bag_path);

// Throws std::runtime_error naming the bag and the problem (unreadable, no camera_info, no IMU or
// IMU -> camera transform when the parameters take it from tf, no simulator truth when asked).
StabiliserRecordingData readStabiliserRecording(const std::string& bag_path,
                                                const GyroFlowParameters& gyro,
                                                LensMotionTarget target,
                                                const LensShiftOptions& lens_options = {});

}  // namespace deep_ois
