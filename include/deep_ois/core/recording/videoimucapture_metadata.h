// The metadata file of the VideoIMUCapture Android app (video_meta.pb3: proto3
// videoimu.VideoCaptureData; field numbers in ../shared/data/videoimucapture_pixel/
// recording_schema.txt): intrinsics, sensor orientation, OIS flags, the gyro and one row per
// frame. Read with the wire-format reader (core/recording/protobuf_wire.h). Pure core: no ROS.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

struct VideoImuCaptureFrameRow {
  int row = 0;                 // 0-based position among the file's video_meta messages
  double stamp_s = 0.0;        // time_ns (Android SENSOR_TIMESTAMP, boot clock) / 1e9
  std::int64_t frame_number = 0;
  double exposure_s = 0.0;
  double frame_duration_s = 0.0;
  double readout_s = 0.0;      // frame_readout_ns: first row to last row
  std::vector<LensShiftLogSample> ois;  // OIS_samples (active-array pixels, sensor axes)
};

struct VideoImuCaptureMetadata {
  std::string source;
  // camera_meta
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();  // fx, fy, cx, cy at the video's size (px)
  int width_px = 0, height_px = 0;                        // resolution (the video as stored)
  int active_array_width_px = 0, active_array_height_px = 0;  // pre-correction active array
  int sensor_orientation_deg = 0;  // clockwise rotation from the sensor's rows to the stored image
  bool optical_image_stabilization = false;
  bool video_stabilization = false;
  // imu: gyro - gyro_drift (uncalibrated gyro minus the phone's own bias estimate), rad/s, the
  // phone's sensor frame (Android: x right, y up, z out of the screen, natural orientation).
  std::vector<ImuSample> gyro;
  bool gyro_drift_subtracted = false;
  std::vector<VideoImuCaptureFrameRow> frames;  // video_meta, in file order
};

// Reads the file. Throws RecordingFormatError naming the file, the message and the byte where it
// breaks: a truncated file, a wrong wire type, a gyro row without three values, stamps that do not
// increase, no frame rows, no camera_meta.
VideoImuCaptureMetadata loadVideoImuCaptureMetadata(const std::string& path);

}  // namespace deep_ois
