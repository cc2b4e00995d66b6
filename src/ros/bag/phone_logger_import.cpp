#include "deep_ois/ros/bag/phone_logger_import.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "deep_ois/core/recording/android_camera_orientation.h"
#include "deep_ois/core/recording/dvs_log_recording.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/core/recording/video_frame_pairing.h"
#include "deep_ois/core/recording/videoimucapture_metadata.h"

namespace deep_ois {

namespace {

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

std::string fixed(double value, int digits) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

// A video decoded front to back (OpenCV's FFmpeg backend: HEVC, H.264, ...).
class VideoDecoder {
 public:
  explicit VideoDecoder(const std::string& path) : path_(path), capture_(path, cv::CAP_FFMPEG) {
    if (!capture_.isOpened()) {
      throw RecordingFormatError(path, 0, "cannot open or decode the video (OpenCV's FFmpeg backend)");
    }
    // Pixels as stored: the importer turns them itself, from the metadata's sensor orientation.
    capture_.set(cv::CAP_PROP_ORIENTATION_AUTO, 0);
  }
  // The next frame (BGR) or an empty Mat at the end; `presentation_s` its presentation time.
  cv::Mat next(double* presentation_s = nullptr) {
    cv::Mat frame;
    if (!capture_.read(frame)) return {};
    if (presentation_s) *presentation_s = capture_.get(cv::CAP_PROP_POS_MSEC) * 1e-3;
    ++position_;
    return frame;
  }
  int position() const { return position_; }  // frames read so far
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  cv::VideoCapture capture_;
  int position_ = 0;
};

cv::Mat prepare(const cv::Mat& stored, const SensorOrientationTurn& turn, double scale, bool grey) {
  cv::Mat image = turn.apply(stored);
  if (scale != 1.0) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_AREA);
  if (grey && image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  return image;
}

void addLensLog(ImportedRecording& out, const std::string& source, std::vector<LensShiftLogSample> samples,
                std::vector<int> lines) {
  out.content.lens_log_source = source;
  out.content.lens_log = std::move(samples);
  out.content.lens_log_lines = std::move(lines);
}

}  // namespace

ImportedRecording importVideoImuCapture(const std::string& video, const std::string& metadata,
                                        const VideoImportOptions& options) {
  if (metadata.empty()) {
    throw RecordingFormatError(video, 0,
                               "a video without metadata: VideoIMUCapture writes video_meta.pb3 beside the video "
                               "(stamps, gyro, intrinsics); without it the frames have no time");
  }
  if (!(options.image_scale > 0.0 && options.image_scale <= 1.0)) {
    throw std::invalid_argument("image scale must be in (0, 1], got " + std::to_string(options.image_scale));
  }
  const VideoImuCaptureMetadata meta = loadVideoImuCaptureMetadata(metadata);
  if (video.empty() && !options.without_images) {
    throw RecordingFormatError(metadata, 0,
                               "metadata without video: " + std::to_string(meta.frames.size()) +
                                   " frame rows but no video file (give the .mp4 beside it, or --without-images "
                                   "for a bag of camera_info, gyro and OIS log alone)");
  }
  ImportedRecording out;
  const SensorOrientationTurn turn = sensorOrientationTurn(meta.sensor_orientation_deg);
  const cv::Size stored(meta.width_px, meta.height_px);
  const cv::Size sensor = turn.sensorSize(stored);
  const cv::Size written(static_cast<int>(std::lround(sensor.width * options.image_scale)),
                         static_cast<int>(std::lround(sensor.height * options.image_scale)));
  const double sx = static_cast<double>(written.width) / sensor.width;
  const double sy = static_cast<double>(written.height) / sensor.height;
  const Eigen::Vector4d k = turn.intrinsics(meta.intrinsics, stored);
  // Pixel centres at integers: c' = (c + 0.5) * s - 0.5.
  out.content.camera_info = makePinholeCameraInfo(written.width, written.height, k[0] * sx, k[1] * sy,
                                                  (k[2] + 0.5) * sx - 0.5, (k[3] + 0.5) * sy - 0.5);
  out.content.camera_info_source = metadata + " (camera_meta)";
  out.notes.push_back("camera: " + std::to_string(stored.width) + "x" + std::to_string(stored.height) +
                      " as stored, " + turn.describe() + "; written " + std::to_string(written.width) + "x" +
                      std::to_string(written.height) + ", fx " + fixed(k[0] * sx, 1) + " px");
  out.imu_to_camera_rotation = androidBackCameraImuToCamera(meta.sensor_orientation_deg);
  out.imu_to_camera_source = "the Android back-camera convention for SENSOR_ORIENTATION " +
                             std::to_string(meta.sensor_orientation_deg) +
                             " (the metadata has no IMU placement); calibrate checks it";
  std::vector<double> readouts, exposures;
  for (const VideoImuCaptureFrameRow& row : meta.frames) readouts.push_back(row.readout_s), exposures.push_back(row.exposure_s);
  out.readout_s = median(readouts);
  out.exposure_s = median(exposures);
  out.ois_enabled = meta.optical_image_stabilization;
  out.notes.push_back("metadata: " + std::to_string(meta.frames.size()) + " frame rows, " +
                      std::to_string(meta.gyro.size()) + " gyro rows" +
                      (meta.gyro_drift_subtracted ? " (uncalibrated; the phone's drift estimate subtracted)" : "") +
                      ", readout " + fixed(out.readout_s * 1e3, 2) + " ms, exposure " + fixed(out.exposure_s * 1e3, 2) +
                      " ms, OIS " + (meta.optical_image_stabilization ? "on" : "off") + ", video stabilisation " +
                      (meta.video_stabilization ? "ON (electronic warping: the gyro model does not describe it)" : "off"));
  out.content.gyro_source = metadata + " (imu)";
  out.content.gyro = meta.gyro;
  out.content.frames_source = metadata + " (video_meta)";

  std::vector<LensShiftLogSample> ois;
  for (const VideoImuCaptureFrameRow& row : meta.frames) ois.insert(ois.end(), row.ois.begin(), row.ois.end());
  if (!ois.empty()) {
    addLensLog(out, metadata + " (OIS_samples)", std::move(ois), {});
    if (meta.active_array_width_px <= 0) throw RecordingFormatError(metadata, 0, "OIS samples but no pre_correction_active_array_size");
    // OisSample shifts are active-array pixels on the sensor's axes: the frames are on those axes.
    out.lens_convention.scale = static_cast<double>(written.width) / meta.active_array_width_px;
    out.lens_convention_source = "scale = written width " + std::to_string(written.width) + " / active-array width " +
                                 std::to_string(meta.active_array_width_px) +
                                 "; sensor axes (no swap), signs +1: check with calibrate --lens-shift";
  }

  if (options.without_images) {
    for (const VideoImuCaptureFrameRow& row : meta.frames)
      out.content.frames.push_back({row.row, row.stamp_s, "video_meta[" + std::to_string(row.row) + "]"});
    out.notes.push_back("no images: camera_info per metadata row (for train_stabiliser --target log)");
    return out;
  }

  // Pass 1: the image motion between consecutive frames (small grey frames), to pair them.
  if (options.progress_note) options.progress_note("decoding " + video + " for the frame pairing check");
  std::vector<double> presentation_s;
  ConsecutiveImageMotion motion;
  const double motion_scale = 320.0 / std::max(sensor.width, sensor.height);
  {
    VideoDecoder decoder(video);
    for (;;) {
      if (options.max_frames > 0 && decoder.position() >= options.max_frames) break;
      double pts = 0.0;
      const cv::Mat frame = decoder.next(&pts);
      if (frame.empty()) break;
      if (frame.cols != stored.width || frame.rows != stored.height) {
        throw RecordingFormatError(video, 0,
                                   "frame " + std::to_string(decoder.position() - 1) + " is " +
                                       std::to_string(frame.cols) + "x" + std::to_string(frame.rows) + " but " + metadata +
                                       " (camera_meta.resolution) says " + std::to_string(stored.width) + "x" +
                                       std::to_string(stored.height));
      }
      presentation_s.push_back(pts);
      motion.add(prepare(frame, turn, motion_scale, true));
    }
    if (decoder.position() < 3) throw RecordingFormatError(video, 0, "fewer than 3 frames decoded");
  }
  std::vector<double> row_stamps, centre_stamps;
  for (const VideoImuCaptureFrameRow& row : meta.frames) {
    row_stamps.push_back(row.stamp_s);
    // The image centre's capture: middle of its exposure (SENSOR_TIMESTAMP starts the first row's).
    centre_stamps.push_back(row.stamp_s + 0.5 * row.exposure_s + 0.5 * row.readout_s);
  }
  const std::vector<Eigen::Vector2d> gyro_motion =
      gyroImageMotionPx(meta.gyro, centre_stamps, out.imu_to_camera_rotation, k[0] * motion_scale);
  const VideoFramePairing pairing =
      pairVideoFrames(presentation_s, motion.motions_px(), row_stamps, gyro_motion, options.max_shift);
  out.notes.push_back(pairing.summary());
  int shift = pairing.shift;
  if (options.forced_shift) {
    shift = *options.forced_shift;
    out.notes.push_back("frame pairing forced by --frame-shift " + std::to_string(shift) +
                        (shift == pairing.shift ? " (the same as found)" : " (NOT the one the gyro check found)"));
  } else if (!pairing.confident) {
    throw RecordingFormatError(video, 0,
                               "the gyro does not confirm a frame-to-row pairing with " + metadata + ": " +
                                   pairing.summary() +
                                   ". A shaken recording pairs reliably; if you know the shift, give --frame-shift N");
  }
  for (std::size_t j = 0; j < presentation_s.size(); ++j) {
    const long r = static_cast<long>(j) - shift;
    if (r < 0 || r >= static_cast<long>(meta.frames.size())) continue;
    out.content.frames.push_back({static_cast<int>(r), meta.frames[static_cast<std::size_t>(r)].stamp_s,
                                  video + " frame " + std::to_string(j) + " (metadata row " + std::to_string(r) + ")"});
  }
  // Pass 2 (while writing): decode again, front to back, keeping the paired frames.
  auto decoder = std::make_shared<VideoDecoder>(video);
  const std::vector<RecordingFrame> frames = out.content.frames;
  const double scale = options.image_scale;
  const bool grey = options.grey;
  out.content.read_image = [decoder, frames, shift, turn, scale, grey](std::size_t k) -> cv::Mat {
    const int wanted = frames[k].index + shift;  // video frame of row `index`
    cv::Mat frame;
    while (decoder->position() <= wanted) {
      frame = decoder->next();
      if (frame.empty()) return {};  // writeRecordingBag names the frame that could not be decoded
    }
    return prepare(frame, turn, scale, grey);
  };
  return out;
}

ImportedRecording importDvsLogs(const std::string& directory, const DvsImportOptions& options) {
  const DvsLogFiles files = dvsLogLayout(directory);
  const DvsLogRecording logs = loadDvsLogRecording(files);
  ImportedRecording out;
  const double fov = logs.fov > 0 ? logs.fov : 1.27;
  const double f = options.image_width_px / fov;
  out.content.camera_info = makePinholeCameraInfo(options.image_width_px, options.image_height_px, f, f,
                                                  0.5 * (options.image_width_px - 1), 0.5 * (options.image_height_px - 1));
  out.content.camera_info_source = files.calib.empty() ? directory : files.calib;
  out.notes.push_back("camera: no video in the logs; camera_info " + std::to_string(options.image_width_px) + "x" +
                      std::to_string(options.image_height_px) + ", fx = width / fov = " + fixed(f, 1) + " px (fov " +
                      fixed(fov, 3) + (logs.fov > 0 ? " from " + files.calib : std::string(" assumed: no calib.txt")) + ")");
  out.imu_to_camera_rotation = options.imu_to_camera_rotation;
  out.imu_to_camera_source =
      "the DVS logs' gyro columns as logged (wx, wy, wz) on the landscape image: x -> -x, y -> y, z -> -z "
      "(measured on the Pixel 4 logs: the OIS log's x, y are then the image's x, y)";
  out.readout_s = logs.readout_s;
  out.exposure_s = logs.exposure_s;
  out.ois_enabled = true;
  out.notes.push_back("logs: " + std::to_string(logs.frame_stamps_s.size()) + " frames, " +
                      std::to_string(logs.gyro.size()) + " gyro rows, " + std::to_string(logs.ois.size()) +
                      " OIS rows; readout " + fixed(logs.readout_s * 1e3, 3) + " ms (" +
                      std::to_string(logs.readout_rows_differing) + " frames differ), exposure " +
                      fixed(logs.exposure_s * 1e3, 2) + " ms");
  out.content.gyro_source = files.gyro_log;
  out.content.gyro = logs.gyro;
  out.content.frames_source = files.frame_timestamps;
  for (std::size_t k = 0; k < logs.frame_stamps_s.size(); ++k)
    out.content.frames.push_back({static_cast<int>(k), logs.frame_stamps_s[k],
                                  files.frame_timestamps + ":" + std::to_string(logs.frame_lines[k])});
  addLensLog(out, files.ois_log, logs.ois, logs.ois_lines);
  out.lens_convention.scale = static_cast<double>(options.image_width_px) / options.active_array_width_px;
  out.lens_convention_source = "scale = image width " + std::to_string(options.image_width_px) +
                               " / active-array width " + std::to_string(options.active_array_width_px) +
                               "; log x, y = image x, y (no swap, signs +1)";
  return out;
}

std::string importedGyroFlowYaml(const ImportedRecording& recording, const std::string& source) {
  std::ostringstream out;
  out << std::setprecision(12);
  out << "# Gyro flow parameters of " << source << ", written by convert_recording from the logger's metadata.\n"
      << "# Only the camera's own parameters: the others keep the package's values. Live:\n"
      << "#   roslaunch deep_ois deep_ois.launch gyro_config:=<this file> (loaded over config/gyro_flow.yaml)\n"
      << "# Tools: train_stabiliser, predict_lens and evaluate take it as --gyro-config <this file>.\n"
      << "# Exposure (median): " << recording.exposure_s * 1e3 << " ms; OIS " << (recording.ois_enabled ? "on" : "off")
      << ".\n"
      << "# Frames are in the sensor's orientation: rows are read out top to bottom.\n"
      << "readout_time: " << recording.readout_s << "  # logged rolling-shutter readout, s\n"
      << "time_offset: 0.0  # one clock for gyro and frames; calibrate measures the rest\n"
      << "# " << recording.imu_to_camera_source << "\n"
      << "imu_to_camera_rotation: [";
  for (int i = 0; i < 9; ++i) out << (i ? ", " : "") << recording.imu_to_camera_rotation(i / 3, i % 3);
  out << "]\n";
  if (!recording.content.lens_log.empty()) {
    const LensShiftLogConvention& c = recording.lens_convention;
    out << "# lens-shift log: " << recording.lens_convention_source << "\n"
        << "lens_shift_scale: " << c.scale << "\n"
        << "lens_shift_swap_xy: " << (c.swap_xy ? "true" : "false") << "\n"
        << "lens_shift_sign_x: " << c.sign_x << "\n"
        << "lens_shift_sign_y: " << c.sign_y << "\n"
        << "lens_shift_time_offset: " << c.time_offset_s << "\n";
  }
  return out.str();
}

}  // namespace deep_ois
