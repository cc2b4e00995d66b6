// Importers of what phone loggers write, into the RecordingContent that writeRecordingBag turns
// into a bag (one writer for every format):
//  - VideoIMUCapture (Android app): a video file (HEVC/H.264, decoded with OpenCV's FFmpeg
//    backend) + video_meta.pb3;
//  - Google's DVS logs (gyro, OIS and frame-timestamp text files), without video.
// Each also gives what the gyro flow needs beside the bag (readout, IMU-to-camera rotation, the
// lens-shift log convention) and says in `notes` every choice it made.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"

namespace deep_ois {

struct ImportedRecording {
  RecordingContent content;
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();
  std::string imu_to_camera_source;   // where the rotation comes from
  double readout_s = 0.0;             // first row to last row, as the metadata logs it
  double exposure_s = 0.0;            // median exposure
  bool ois_enabled = false;
  LensShiftLogConvention lens_convention;  // scale from the active array; sensor axes, signs +1
  std::string lens_convention_source;
  std::vector<std::string> notes;     // one line each, for the user
};

struct VideoImportOptions {
  double image_scale = 1.0;    // frames (and intrinsics) scaled by this (0 < s <= 1)
  bool grey = false;           // write mono8 instead of rgb8
  int max_frames = 0;          // the first N video frames only (0: all)
  int max_shift = 5;           // frame pairings tried: shifts -N..N
  // A whole-frame shift the user asserts (video frame j = row j - shift) in place of a pairing the
  // gyro check finds not confident; std::nullopt: refuse such a recording.
  std::optional<int> forced_shift;
  bool without_images = false;  // metadata alone (a log-only bag)
  std::function<void(const std::string&)> progress_note;  // e.g. "decoding for the pairing check"
};

// VideoIMUCapture: `video` (may be empty only with without_images) and `metadata` (video_meta.pb3).
// Frames are turned back to the sensor's orientation (rows read out in order), the intrinsics with
// them. Throws RecordingFormatError naming the file (and the row / message) for bad input, a video
// without metadata or the reverse, and a pairing the gyro does not confirm.
ImportedRecording importVideoImuCapture(const std::string& video, const std::string& metadata,
                                        const VideoImportOptions& options);

struct DvsImportOptions {
  int image_width_px = 1920;           // the images the bag describes (no video in the logs)
  int image_height_px = 1080;
  int active_array_width_px = 4032;    // Pixel 4 main camera (the OIS log's unit)
  // R_cam_imu of the logs' gyro columns (wx, wy, wz as logged) and the landscape image: x -> -x,
  // y -> y, z -> -z. Measured on the Pixel 4 logs (../shared/data/pixel4_dvs_ois): with it the OIS
  // log's x, y are the image's x, y (train_stabiliser --target log fits a gain of about +identity);
  // its README's finding. --imu-to-camera overrides it.
  Eigen::Matrix3d imu_to_camera_rotation = (Eigen::Matrix3d() << -1, 0, 0, 0, 1, 0, 0, 0, -1).finished();
};

// Google DVS logs in `directory` (dvsLogLayout): a log-only recording (camera_info per frame).
ImportedRecording importDvsLogs(const std::string& directory, const DvsImportOptions& options);

// The gyro flow parameters the recording determines (readout_time, imu_to_camera_rotation,
// lens_shift_*), as YAML to load after config/gyro_flow.yaml and to give to calibrate /
// train_stabiliser as --gyro-config.
std::string importedGyroFlowYaml(const ImportedRecording& recording, const std::string& source);

}  // namespace deep_ois
