#include "deep_ois/ros/bag/phone_recording_bag.h"

#include <camera_calibration_parsers/parse.h>
#include <cv_bridge/cv_bridge.h>
#include <deep_ois/LensShiftSample.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/image_encodings.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/ois/lens_shift_log_repair.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/messages/recording_bag_messages.h"

namespace deep_ois {

namespace {

void checkOptions(const PhoneRecordingBagOptions& options) {
  auto fail = [](const std::string& problem) {
    throw std::invalid_argument("phone recording bag options: " + problem);
  };
  for (const std::string* name : {&options.image_topic, &options.camera_info_topic, &options.imu_topic,
                                  &options.tf_static_topic, &options.camera_frame_id, &options.imu_frame_id}) {
    if (name->empty()) fail("topics and frame ids must not be empty");
  }
  if (options.camera_frame_id == options.imu_frame_id) {
    fail("the camera and IMU frame ids must differ (both '" + options.imu_frame_id + "')");
  }
  if (!isProperRotation(options.imu_to_camera_rotation)) {
    const Eigen::Matrix3d& R = options.imu_to_camera_rotation;
    const bool reflection = isProperRotation(-R);  // orthonormal with det -1: a bare axis swap
    fail(std::string("the IMU-to-camera rotation is not a proper rotation (orthonormal, det +1)") +
         (reflection ? ": it is a reflection (det -1), as a bare axis swap such as (wy, wx, wz) is; no "
                       "physical mount is, so one axis must also change sign"
                     : "") +
         ". If the mount is unknown, convert with any proper rotation (e.g. the identity, "
         "--imu-to-camera 1,0,0,0,1,0,0,0,1), run `rosrun deep_ois calibrate --bag OUT.bag --out "
         "cal.yaml` (it searches all 24 axis permutations and refines the mount) and use its "
         "imu_to_camera_rotation");
  }
  if (!std::isfinite(options.clock_offset_s) || !std::isfinite(options.frame_stamp_offset_s)) {
    fail("stamp offsets must be finite");
  }
  if (!(options.imu_margin_s >= 0.0)) fail("the IMU margin must be >= 0 s");
}

std::string describeSeconds(double s) {
  std::ostringstream out;
  out.precision(6);
  out << std::fixed << s << " s";
  return out.str();
}

// An 8-bit image as OpenCV decodes it (grey, BGR or BGRA) as mono8 or rgb8.
cv::Mat toBagImage(const cv::Mat& decoded, const std::string& label, std::string& encoding) {
  if (decoded.empty()) throw RecordingFormatError(label, 0, "cannot read or decode the image");
  if (decoded.depth() != CV_8U) {
    throw RecordingFormatError(label, 0, "only 8-bit images are supported (rgb8 or mono8)");
  }
  cv::Mat frame;
  switch (decoded.channels()) {
    case 1:
      encoding = sensor_msgs::image_encodings::MONO8;
      return decoded;
    case 3:
      cv::cvtColor(decoded, frame, cv::COLOR_BGR2RGB);
      break;
    case 4:
      cv::cvtColor(decoded, frame, cv::COLOR_BGRA2RGB);
      break;
    default:
      throw RecordingFormatError(label, 0, "unsupported channel count " + std::to_string(decoded.channels()));
  }
  encoding = sensor_msgs::image_encodings::RGB8;
  return frame;
}

}  // namespace

PhoneRecordingFiles cc9proLayout(const std::string& directory) {
  PhoneRecordingFiles files;
  files.gyro_csv = directory + "/gyro.txt";
  files.frame_stamps = directory + "/framestamp.txt";
  // No frames/ folder: a recording of logs alone (train_stabiliser --target log reads no image).
  if (std::filesystem::is_directory(directory + "/frames")) files.images_dir = directory + "/frames";
  if (std::ifstream(directory + "/lens_shift.txt").good()) files.lens_shift_csv = directory + "/lens_shift.txt";
  return files;
}

Eigen::Matrix3d cc9proImuToCameraRotation() {
  Eigen::Matrix3d R;
  R << 0, -1, 0,  //
      -1, 0, 0,   //
      0, 0, -1;
  return R;
}

sensor_msgs::CameraInfo loadCameraInfoFile(const std::string& path) {
  if (path.empty()) throw RecordingFormatError("(camera info)", 0, "no camera calibration file given");
  if (!std::ifstream(path).good()) throw RecordingFormatError(path, 0, "cannot open file for reading");
  sensor_msgs::CameraInfo info;
  std::string camera_name;
  // The parser logs its own detail (the YAML error with its line) before returning false.
  if (!camera_calibration_parsers::readCalibration(path, camera_name, info)) {
    throw RecordingFormatError(path, 0,
                               "not a ROS camera calibration file (YAML with image_width, "
                               "image_height, camera_matrix, distortion_model, "
                               "distortion_coefficients, ...; see the error logged above)");
  }
  CameraModel camera;
  const std::string problem = toCameraModel(info, camera);
  if (!problem.empty()) throw RecordingFormatError(path, 0, problem);
  return info;
}

sensor_msgs::CameraInfo makePinholeCameraInfo(int width_px, int height_px, double fx_px, double fy_px,
                                              double cx_px, double cy_px) {
  sensor_msgs::CameraInfo info;
  info.width = static_cast<unsigned>(width_px);
  info.height = static_cast<unsigned>(height_px);
  info.distortion_model = "plumb_bob";
  info.D = {0.0, 0.0, 0.0, 0.0, 0.0};
  info.K = {fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {fx_px, 0.0, cx_px, 0.0, 0.0, fy_px, cy_px, 0.0, 0.0, 0.0, 1.0, 0.0};
  return info;
}

PhoneRecordingBagStats writePhoneRecordingBag(const PhoneRecordingFiles& files, const std::string& bag_path,
                                              const PhoneRecordingBagOptions& options,
                                              const std::function<void(int, int)>& progress) {
  checkOptions(options);
  // Everything that can be checked without decoding the images is checked before the bag exists.
  RecordingContent content;
  content.gyro_source = files.gyro_csv;
  content.gyro = loadGyroCsv(files.gyro_csv);
  content.frames_source = files.frame_stamps;
  const std::vector<double> stamps_s = loadFrameStamps(files.frame_stamps);
  content.camera_info_source = files.camera_info;
  content.camera_info = loadCameraInfoFile(files.camera_info);
  if (!files.lens_shift_csv.empty()) {
    content.lens_log_source = files.lens_shift_csv;
    content.lens_log = loadLensShiftCsv(files.lens_shift_csv, &content.lens_log_lines);
  }
  if (files.images_dir.empty()) {
    // A log-only recording: every stamp line is a frame, with no image.
    for (std::size_t k = 0; k < stamps_s.size(); ++k)
      content.frames.push_back({static_cast<int>(k), stamps_s[k], files.frame_stamps + ":" + std::to_string(k + 1)});
    return writeRecordingBag(std::move(content), bag_path, options, progress);
  }
  const std::vector<FrameImageFile> images = listFrameImages(files.images_dir);
  // Numbering first, as a whole: image files numbered from 1 against a stamp list whose line 0
  // is frame 0 would otherwise pair every image with the previous frame's stamp, unnoticed until
  // the last image finds no line.
  if (images.back().index >= static_cast<int>(stamps_s.size())) {
    const bool from_one = images.front().index == 1 && images.back().index == static_cast<int>(stamps_s.size());
    throw RecordingFormatError(
        files.images_dir, 0,
        "the image files are numbered " + std::to_string(images.front().index) + ".." +
            std::to_string(images.back().index) + " but " + files.frame_stamps + " has " +
            std::to_string(stamps_s.size()) + " lines, i.e. frames 0.." + std::to_string(stamps_s.size() - 1) +
            " (line i is frame i, from 0)" +
            (from_one ? ": the files look numbered from 1; renumber them from 0 (or drop the first stamp "
                        "line if the first stamp belongs to no image)"
                      : ": image and stamp numbering do not match"));
  }
  for (const FrameImageFile& image : images) content.frames.push_back({image.index, stamps_s[image.index], image.path});
  content.frames_source = files.frame_stamps + " and " + files.images_dir;
  content.read_image = [images](std::size_t k) { return cv::imread(images[k].path, cv::IMREAD_UNCHANGED); };
  return writeRecordingBag(std::move(content), bag_path, options, progress);
}

PhoneRecordingBagStats writeRecordingBag(RecordingContent content, const std::string& bag_path,
                                         const PhoneRecordingBagOptions& options,
                                         const std::function<void(int, int)>& progress) {
  checkOptions(options);
  const std::vector<ImuSample>& gyro = content.gyro;
  std::vector<RecordingFrame>& images = content.frames;
  sensor_msgs::CameraInfo& info = content.camera_info;
  if (gyro.empty()) throw RecordingFormatError(content.gyro_source, 0, "no gyro samples");
  if (images.empty()) throw RecordingFormatError(content.frames_source, 0, "no frames");
  if (!(options.span_to_s > options.span_from_s)) throw std::invalid_argument("phone recording bag options: the span is empty");
  int frames_outside_span = 0;
  if (options.span_from_s > 0.0 || std::isfinite(options.span_to_s)) {
    const double start_s = images.front().stamp_s;
    std::vector<RecordingFrame> inside;
    std::vector<std::size_t> positions;  // into the original frames, for read_image
    for (std::size_t k = 0; k < images.size(); ++k) {
      const double t = images[k].stamp_s - start_s;
      if (t >= options.span_from_s && t < options.span_to_s) {
        inside.push_back(images[k]);
        positions.push_back(k);
      } else {
        ++frames_outside_span;
      }
    }
    if (inside.size() < 2) {
      throw RecordingFormatError(content.frames_source, 0,
                                 "fewer than two frames between " + describeSeconds(options.span_from_s) + " and " +
                                     describeSeconds(options.span_to_s) + " after the first frame");
    }
    images = std::move(inside);
    if (content.read_image) {
      content.read_image = [read = std::move(content.read_image), positions](std::size_t k) { return read(positions[k]); };
    }
  }
  const LensShiftLogRepair lens_repair =
      content.lens_log.empty() ? LensShiftLogRepair{}
                               : [&] {
                                   try {
                                     return repairLensShiftLog(content.lens_log, content.lens_log_source,
                                                               content.lens_log_lines);
                                   } catch (const std::invalid_argument& e) {
                                     throw RecordingFormatError(content.lens_log_source, 0, e.what());
                                   }
                                 }();
  const std::vector<LensShiftLogSample>& lens_log = lens_repair.samples;
  // Recording time of a frame's stamp; the gyro must cover every frame, or (drop_uncovered_frames)
  // the frames it does not cover are left out and counted.
  auto frameTime = [&](const RecordingFrame& frame) { return frame.stamp_s + options.frame_stamp_offset_s; };
  const double uncovered_first_s = frameTime(images.front()), uncovered_last_s = frameTime(images.back());
  PhoneRecordingBagStats stats;
  stats.frames_outside_span = frames_outside_span;
  stats.images = static_cast<bool>(content.read_image);
  stats.lens_shift_repeats_dropped = lens_repair.repeats_dropped;
  stats.lens_shift_steps_back = lens_repair.steps_back;
  // No overlap at all is not a gyro started late: the two are stamped on different clocks (e.g. a
  // boot clock and Unix time, or ns read as us), which no --drop-uncovered-frames can fix.
  // (A second apart at least: a gyro that merely stopped early is the message below.)
  if (frameTime(images.back()) < gyro.front().stamp_s - 1.0 || frameTime(images.front()) > gyro.back().stamp_s + 1.0) {
    const double gap_s = frameTime(images.front()) - gyro.front().stamp_s;
    throw RecordingFormatError(
        content.frames_source, 0,
        "stamps on two clocks: the frames (" + describeSeconds(uncovered_first_s) + " .. " +
            describeSeconds(uncovered_last_s) + ", first at " + images.front().label + ") and the gyro (" +
            describeSeconds(gyro.front().stamp_s) + " .. " + describeSeconds(gyro.back().stamp_s) + ", " +
            content.gyro_source + ") do not overlap at all (first frame - first gyro sample = " +
            describeSeconds(gap_s) + "); both must be on one clock (check the units and the clock of each file)");
  }
  // Which of content.frames are written (their positions, so read_image gets the right k).
  std::vector<std::size_t> kept;
  for (std::size_t k = 0; k < images.size(); ++k) {
    const double t = frameTime(images[k]);
    if (!options.drop_uncovered_frames || (t >= gyro.front().stamp_s && t <= gyro.back().stamp_s)) {
      kept.push_back(k);
    } else {
      ++stats.dropped_uncovered_frames;
    }
  }
  if (options.drop_uncovered_frames && kept.size() < 2) {
    throw RecordingFormatError(content.gyro_source, 0,
                               "the gyro samples (" + describeSeconds(gyro.front().stamp_s) + " .. " +
                                   describeSeconds(gyro.back().stamp_s) + ") cover " + std::to_string(kept.size()) +
                                   " of the " + std::to_string(images.size()) + " frames (" +
                                   describeSeconds(uncovered_first_s) + " .. " + describeSeconds(uncovered_last_s) +
                                   "): fewer than two are left");
  }
  const RecordingFrame& first_frame = images[kept.front()];
  const RecordingFrame& last_frame = images[kept.back()];
  const double first_frame_s = frameTime(first_frame);
  const double last_frame_s = frameTime(last_frame);
  if (gyro.front().stamp_s > first_frame_s || gyro.back().stamp_s < last_frame_s) {
    int uncovered = 0;
    for (std::size_t k : kept)
      uncovered += frameTime(images[k]) < gyro.front().stamp_s || frameTime(images[k]) > gyro.back().stamp_s;
    throw RecordingFormatError(content.gyro_source, 0,
                               "the gyro samples (" + describeSeconds(gyro.front().stamp_s) + " .. " +
                                   describeSeconds(gyro.back().stamp_s) + ") do not cover the frames (" +
                                   describeSeconds(first_frame_s) + " .. " + describeSeconds(last_frame_s) +
                                   ", from " + content.frames_source + "): " + std::to_string(uncovered) +
                                   " of " + std::to_string(kept.size()) +
                                   " frames lie outside; --drop-uncovered-frames leaves them out");
  }

  stats.first_frame_index = first_frame.index;
  stats.last_frame_index = last_frame.index;
  stats.skipped_frame_indices = stats.last_frame_index - stats.first_frame_index + 1 - static_cast<int>(kept.size());
  std::vector<sensor_msgs::Imu> imu;
  for (const ImuSample& sample : gyro) {
    if (sample.stamp_s < first_frame_s - options.imu_margin_s) continue;
    if (sample.stamp_s > last_frame_s + options.imu_margin_s) break;
    imu.push_back(makeGyroImuMessage(toRosTime(sample.stamp_s, options.clock_offset_s),
                                     options.imu_frame_id, sample.angular_velocity_rad_s));
    imu.back().linear_acceleration_covariance[0] = -1.0;  // no accelerometer in the recording
  }

  rosbag::Bag bag;
  bag.open(bag_path, rosbag::bagmode::Write);
  bag.setCompression(options.compression);
  try {
    const ros::Time first_stamp = toRosTime(first_frame.stamp_s, options.clock_offset_s + options.frame_stamp_offset_s);
    const ros::Time tf_time = imu.empty() ? first_stamp : std::min(first_stamp, imu.front().header.stamp);
    writeLatched(bag, options.tf_static_topic, tf_time,
                 makeImuToCameraTransform(tf_time, options.imu_frame_id, options.camera_frame_id,
                                          options.imu_to_camera_rotation),
                 "/deep_ois_convert_recording");
    std::size_t next_imu = 0;
    stats.encoding = stats.images ? "" : "none";
    for (std::size_t n = 0; n < kept.size(); ++n) {
      const RecordingFrame& frame = images[kept[n]];
      std_msgs::Header header;
      header.stamp = toRosTime(frame.stamp_s, options.clock_offset_s + options.frame_stamp_offset_s);
      header.frame_id = options.camera_frame_id;
      while (next_imu < imu.size() && imu[next_imu].header.stamp <= header.stamp) {
        bag.write(options.imu_topic, imu[next_imu].header.stamp, imu[next_imu]);
        ++next_imu;
      }
      if (stats.images) {
        std::string encoding;
        const cv::Mat image = toBagImage(content.read_image(kept[n]), frame.label, encoding);
        if (image.cols != static_cast<int>(info.width) || image.rows != static_cast<int>(info.height)) {
          throw RecordingFormatError(frame.label, 0,
                                     "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                                         " but the calibration " + content.camera_info_source + " is for " +
                                         std::to_string(info.width) + "x" + std::to_string(info.height));
        }
        if (n == 0) stats.encoding = encoding;
        if (encoding != stats.encoding) {
          throw RecordingFormatError(frame.label, 0,
                                     "image is " + encoding + " but the first frame " + first_frame.label + " is " +
                                         stats.encoding);
        }
        bag.write(options.image_topic, header.stamp, *cv_bridge::CvImage(header, encoding, image).toImageMsg());
      }
      info.header = header;
      bag.write(options.camera_info_topic, header.stamp, info);
      if (n == 0) stats.first_frame_stamp = header.stamp;
      stats.last_frame_stamp = header.stamp;
      ++stats.frames;
      if (progress) progress(stats.frames, static_cast<int>(kept.size()));
    }
    for (; next_imu < imu.size(); ++next_imu) {
      bag.write(options.imu_topic, imu[next_imu].header.stamp, imu[next_imu]);
    }
    // The lens log (a bag's index orders the messages by time, whatever the write order).
    for (const LensShiftLogSample& sample : lens_log) {
      if (sample.stamp_s < first_frame_s - options.imu_margin_s) continue;
      if (sample.stamp_s > last_frame_s + options.imu_margin_s) break;
      LensShiftSample msg;
      msg.header.stamp = toRosTime(sample.stamp_s, options.clock_offset_s);
      msg.header.frame_id = options.camera_frame_id;
      msg.x = sample.logged.x();
      msg.y = sample.logged.y();
      msg.covariance = {-1.0, 0.0, 0.0, 0.0};
      if (sample.covariance) {
        for (int i = 0; i < 4; ++i) msg.covariance[i] = (*sample.covariance)(i / 2, i % 2);
      }
      bag.write(options.lens_shift_topic, msg.header.stamp, msg);
      ++stats.lens_shift_messages;
    }
    stats.imu_messages = static_cast<int>(imu.size());
    stats.width_px = static_cast<int>(info.width);
    stats.height_px = static_cast<int>(info.height);
  } catch (...) {
    // A half-written bag would look like a short recording: remove it.
    bag.close();
    std::remove(bag_path.c_str());
    throw;
  }
  bag.close();
  return stats;
}

}  // namespace deep_ois
