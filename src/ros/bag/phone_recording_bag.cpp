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
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
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

sensor_msgs::CameraInfo loadCameraInfo(const std::string& path) {
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

std::string describeSeconds(double s) {
  std::ostringstream out;
  out.precision(6);
  out << std::fixed << s << " s";
  return out.str();
}

// Decodes one frame as mono8 or rgb8 (OpenCV decodes colour as BGR).
cv::Mat readFrame(const FrameImageFile& file, std::string& encoding) {
  const cv::Mat decoded = cv::imread(file.path, cv::IMREAD_UNCHANGED);
  if (decoded.empty()) throw RecordingFormatError(file.path, 0, "cannot read or decode the image");
  if (decoded.depth() != CV_8U) {
    throw RecordingFormatError(file.path, 0, "only 8-bit images are supported (rgb8 or mono8)");
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
      throw RecordingFormatError(file.path, 0,
                                 "unsupported channel count " + std::to_string(decoded.channels()));
  }
  encoding = sensor_msgs::image_encodings::RGB8;
  return frame;
}

}  // namespace

PhoneRecordingFiles cc9proLayout(const std::string& directory) {
  PhoneRecordingFiles files;
  files.gyro_csv = directory + "/gyro.txt";
  files.frame_stamps = directory + "/framestamp.txt";
  files.images_dir = directory + "/frames";
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

PhoneRecordingBagStats writePhoneRecordingBag(const PhoneRecordingFiles& files, const std::string& bag_path,
                                              const PhoneRecordingBagOptions& options,
                                              const std::function<void(int, int)>& progress) {
  checkOptions(options);
  // Everything that can be checked without decoding the images is checked before the bag exists.
  const std::vector<ImuSample> gyro = loadGyroCsv(files.gyro_csv);
  const std::vector<double> stamps_s = loadFrameStamps(files.frame_stamps);
  std::vector<FrameImageFile> images = listFrameImages(files.images_dir);
  sensor_msgs::CameraInfo info = loadCameraInfo(files.camera_info);
  const std::vector<LensShiftLogSample> lens_log =
      files.lens_shift_csv.empty() ? std::vector<LensShiftLogSample>{} : loadLensShiftCsv(files.lens_shift_csv);
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
  for (const FrameImageFile& image : images) {
    if (image.index >= static_cast<int>(stamps_s.size())) {
      throw RecordingFormatError(image.path, 0,
                                 "frame index " + std::to_string(image.index) + " has no stamp: " +
                                     files.frame_stamps + " has " + std::to_string(stamps_s.size()) +
                                     " lines (line i is frame i, from 0)");
    }
  }
  // Recording time of a frame's stamp; the gyro must cover every frame, or (drop_uncovered_frames)
  // the frames it does not cover are left out and counted.
  auto frameTime = [&](const FrameImageFile& image) { return stamps_s[image.index] + options.frame_stamp_offset_s; };
  const double uncovered_first_s = frameTime(images.front()), uncovered_last_s = frameTime(images.back());
  PhoneRecordingBagStats stats;
  if (options.drop_uncovered_frames) {
    std::vector<FrameImageFile> covered;
    for (const FrameImageFile& image : images) {
      const double t = frameTime(image);
      if (t >= gyro.front().stamp_s && t <= gyro.back().stamp_s) {
        covered.push_back(image);
      } else {
        ++stats.dropped_uncovered_frames;
      }
    }
    if (covered.size() < 2) {
      throw RecordingFormatError(files.gyro_csv, 0,
                                 "the gyro samples (" + describeSeconds(gyro.front().stamp_s) + " .. " +
                                     describeSeconds(gyro.back().stamp_s) + ") cover " +
                                     std::to_string(covered.size()) + " of the " + std::to_string(images.size()) +
                                     " frames (" + describeSeconds(uncovered_first_s) + " .. " +
                                     describeSeconds(uncovered_last_s) + "): fewer than two are left");
    }
    images = std::move(covered);
  }
  const double first_frame_s = frameTime(images.front());
  const double last_frame_s = frameTime(images.back());
  if (gyro.front().stamp_s > first_frame_s || gyro.back().stamp_s < last_frame_s) {
    int uncovered = 0;
    for (const FrameImageFile& image : images)
      uncovered += frameTime(image) < gyro.front().stamp_s || frameTime(image) > gyro.back().stamp_s;
    throw RecordingFormatError(files.gyro_csv, 0,
                               "the gyro samples (" + describeSeconds(gyro.front().stamp_s) + " .. " +
                                   describeSeconds(gyro.back().stamp_s) +
                                   ") do not cover the frames (" + describeSeconds(first_frame_s) +
                                   " .. " + describeSeconds(last_frame_s) + ", from " +
                                   files.frame_stamps + " and " + files.images_dir + "): " +
                                   std::to_string(uncovered) + " of " + std::to_string(images.size()) +
                                   " frames lie outside; --drop-uncovered-frames leaves them out");
  }

  stats.first_frame_index = images.front().index;
  stats.last_frame_index = images.back().index;
  stats.skipped_frame_indices = stats.last_frame_index - stats.first_frame_index + 1 -
                                static_cast<int>(images.size());
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
    const ros::Time first_stamp =
        toRosTime(stamps_s[images.front().index], options.clock_offset_s + options.frame_stamp_offset_s);
    const ros::Time tf_time = imu.empty() ? first_stamp : std::min(first_stamp, imu.front().header.stamp);
    writeLatched(bag, options.tf_static_topic, tf_time,
                 makeImuToCameraTransform(tf_time, options.imu_frame_id, options.camera_frame_id,
                                          options.imu_to_camera_rotation),
                 "/deep_ois_convert_recording");
    std::size_t next_imu = 0;
    for (std::size_t k = 0; k < images.size(); ++k) {
      const FrameImageFile& file = images[k];
      std::string encoding;
      const cv::Mat frame = readFrame(file, encoding);
      if (frame.cols != static_cast<int>(info.width) || frame.rows != static_cast<int>(info.height)) {
        throw RecordingFormatError(file.path, 0,
                                   "image is " + std::to_string(frame.cols) + "x" + std::to_string(frame.rows) +
                                       " but the calibration " + files.camera_info + " is for " +
                                       std::to_string(info.width) + "x" + std::to_string(info.height));
      }
      if (k == 0) stats.encoding = encoding;
      if (encoding != stats.encoding) {
        throw RecordingFormatError(file.path, 0,
                                   "image is " + encoding + " but the first frame " +
                                       images.front().path + " is " + stats.encoding);
      }
      std_msgs::Header header;
      header.stamp =
          toRosTime(stamps_s[file.index], options.clock_offset_s + options.frame_stamp_offset_s);
      header.frame_id = options.camera_frame_id;
      while (next_imu < imu.size() && imu[next_imu].header.stamp <= header.stamp) {
        bag.write(options.imu_topic, imu[next_imu].header.stamp, imu[next_imu]);
        ++next_imu;
      }
      bag.write(options.image_topic, header.stamp, *cv_bridge::CvImage(header, encoding, frame).toImageMsg());
      info.header = header;
      bag.write(options.camera_info_topic, header.stamp, info);
      if (k == 0) stats.first_frame_stamp = header.stamp;
      stats.last_frame_stamp = header.stamp;
      ++stats.frames;
      if (progress) progress(stats.frames, static_cast<int>(images.size()));
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
