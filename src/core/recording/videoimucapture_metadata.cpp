#include "deep_ois/core/recording/videoimucapture_metadata.h"

#include <cmath>

#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/core/recording/protobuf_wire.h"

namespace deep_ois {

namespace {

void readSize(ProtobufMessageReader message, int& width, int& height) {
  ProtobufField f;
  while (message.next(f)) {
    if (f.number == 1) width = static_cast<int>(message.int64(f, "width"));
    if (f.number == 2) height = static_cast<int>(message.int64(f, "height"));
  }
}

void readCameraMeta(ProtobufMessageReader message, VideoImuCaptureMetadata& out) {
  ProtobufField f;
  std::vector<float> intrinsics;
  while (message.next(f)) {
    switch (f.number) {
      case 1: message.appendFloats(f, "intrinsic_params", intrinsics); break;
      case 3: out.optical_image_stabilization = message.boolean(f, "optical_image_stabilization"); break;
      case 4: out.video_stabilization = message.boolean(f, "video_stabilization"); break;
      case 11: readSize(message.child(f, "resolution"), out.width_px, out.height_px); break;
      case 12:
        readSize(message.child(f, "pre_correction_active_array_size"), out.active_array_width_px,
                 out.active_array_height_px);
        break;
      case 14: out.sensor_orientation_deg = static_cast<int>(message.int64(f, "sensor_orientation")); break;
      default: break;
    }
  }
  if (intrinsics.size() < 4) message.fail(0, "intrinsic_params has " + std::to_string(intrinsics.size()) + " values, expected fx, fy, cx, cy[, s]");
  out.intrinsics = Eigen::Vector4d(intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3]);
}

ImuSample readImu(ProtobufMessageReader message, bool& drift_subtracted) {
  ProtobufField f;
  std::vector<float> gyro, drift;
  std::int64_t time_ns = -1;
  std::size_t start = 0;
  while (message.next(f)) {
    if (start == 0) start = f.offset;
    if (f.number == 1) time_ns = message.int64(f, "time_ns");
    if (f.number == 2) message.appendFloats(f, "gyro", gyro);
    if (f.number == 3) message.appendFloats(f, "gyro_drift", drift);
  }
  if (time_ns < 0) message.fail(start, "no time_ns");
  if (gyro.size() != 3) message.fail(start, "gyro has " + std::to_string(gyro.size()) + " values, expected 3");
  ImuSample sample;
  sample.stamp_s = static_cast<double>(time_ns) * 1e-9;
  sample.angular_velocity_rad_s = Eigen::Vector3d(gyro[0], gyro[1], gyro[2]);
  // Android's uncalibrated gyro comes with the phone's own drift estimate: calibrated = gyro - drift.
  if (drift.size() == 3) {
    sample.angular_velocity_rad_s -= Eigen::Vector3d(drift[0], drift[1], drift[2]);
    drift_subtracted = true;
  }
  return sample;
}

LensShiftLogSample readOisSample(ProtobufMessageReader message) {
  ProtobufField f;
  LensShiftLogSample sample;
  sample.logged = Eigen::Vector2d::Zero();
  while (message.next(f)) {
    if (f.number == 1) sample.stamp_s = static_cast<double>(message.int64(f, "time_ns")) * 1e-9;
    if (f.number == 2) sample.logged.x() = message.float32(f, "x_shift");
    if (f.number == 3) sample.logged.y() = message.float32(f, "y_shift");
  }
  return sample;
}

VideoImuCaptureFrameRow readFrameRow(ProtobufMessageReader message, int row) {
  ProtobufField f;
  VideoImuCaptureFrameRow frame;
  frame.row = row;
  bool has_time = false;
  int ois = 0;
  while (message.next(f)) {
    switch (f.number) {
      case 1: frame.stamp_s = static_cast<double>(message.int64(f, "time_ns")) * 1e-9; has_time = true; break;
      case 2: frame.frame_number = message.int64(f, "frame_number"); break;
      case 3: frame.exposure_s = static_cast<double>(message.int64(f, "exposure_time_ns")) * 1e-9; break;
      case 4: frame.frame_duration_s = static_cast<double>(message.int64(f, "frame_duration_ns")) * 1e-9; break;
      case 5: frame.readout_s = static_cast<double>(message.int64(f, "frame_readout_ns")) * 1e-9; break;
      case 10: frame.ois.push_back(readOisSample(message.child(f, "OIS_samples[" + std::to_string(ois++) + "]"))); break;
      default: break;
    }
  }
  if (!has_time) message.fail(0, "no time_ns");
  return frame;
}

}  // namespace

VideoImuCaptureMetadata loadVideoImuCaptureMetadata(const std::string& path) {
  const std::vector<std::uint8_t> bytes = readBinaryFile(path);
  if (bytes.empty()) throw RecordingFormatError(path, 0, "empty file (expected a videoimu.VideoCaptureData protobuf)");
  VideoImuCaptureMetadata out;
  out.source = path;
  ProtobufMessageReader top(bytes.data(), bytes.size(), 0, path, "VideoCaptureData");
  ProtobufField f;
  bool has_camera = false;
  int imu_rows = 0;
  auto next = [&]() {
    try {
      return top.next(f);
    } catch (const RecordingFormatError& e) {
      // Say where in the recording it broke, as a row count.
      throw RecordingFormatError(path, 0,
                                 e.problem() + " (after " + std::to_string(imu_rows) + " imu rows and " +
                                     std::to_string(out.frames.size()) + " video_meta rows)");
    }
  };
  while (next()) {
    if (f.number == 2) {
      readCameraMeta(top.child(f, "camera_meta"), out);
      has_camera = true;
    } else if (f.number == 4) {
      const std::string name = "imu[" + std::to_string(imu_rows++) + "]";
      const ImuSample sample = readImu(top.child(f, name), out.gyro_drift_subtracted);
      if (!out.gyro.empty() && !(sample.stamp_s > out.gyro.back().stamp_s)) {
        top.fail(f.offset, name + ": time " + std::to_string(sample.stamp_s) + " s does not increase (previous " +
                               std::to_string(out.gyro.back().stamp_s) + " s)");
      }
      out.gyro.push_back(sample);
    } else if (f.number == 5) {
      const int row = static_cast<int>(out.frames.size());
      const VideoImuCaptureFrameRow frame =
          readFrameRow(top.child(f, "video_meta[" + std::to_string(row) + "]"), row);
      if (!out.frames.empty() && !(frame.stamp_s > out.frames.back().stamp_s)) {
        top.fail(f.offset, "video_meta[" + std::to_string(row) + "]: time " + std::to_string(frame.stamp_s) +
                               " s does not increase");
      }
      out.frames.push_back(frame);
    }
  }
  if (!has_camera) throw RecordingFormatError(path, 0, "no camera_meta (field 2): not a VideoCaptureData file?");
  if (out.width_px <= 0 || out.height_px <= 0) throw RecordingFormatError(path, 0, "camera_meta has no resolution");
  if (out.gyro.empty()) throw RecordingFormatError(path, 0, "no imu rows (field 4)");
  if (out.frames.empty()) throw RecordingFormatError(path, 0, "no video_meta rows (field 5)");
  return out;
}

}  // namespace deep_ois
