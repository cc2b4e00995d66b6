// Converts a phone recording in the cc9pro layout (gyro CSV, frame stamp list, a folder of frame
// images, camera intrinsics) into the rosbag a robot would have recorded: camera images,
// camera_info, gyro Imu messages and the static IMU -> camera transform.
#pragma once

#include <rosbag/bag.h>

#include <sensor_msgs/CameraInfo.h>

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

// Where the parts of a recording are.
struct PhoneRecordingFiles {
  std::string gyro_csv;      // rows wx,wy,wz,t: rad/s in the IMU frame, seconds
  std::string frame_stamps;  // line i (0-based) = stamp of frame i, seconds, same clock as the gyro
  // Frame images, the file name ending in the frame index. Empty: a recording without images (a
  // lens log for train_stabiliser --target log): the bag holds camera_info per frame stamp alone.
  std::string images_dir;
  std::string camera_info;   // ROS camera calibration file (YAML or INI, camera_calibration_parsers)
  // Optional: the camera's lens-shift log, rows t,x,y[,cxx,cxy,cyy] on the frames' clock
  // (parseLensShiftCsv in core/recording/phone_recording.h; docs/lens_shift_logs.md).
  std::string lens_shift_csv;
};

// The cc9pro layout under `directory`: gyro.txt, framestamp.txt, frames/ when that folder exists
// (else none: a log-only recording), and lens_shift.txt when that file exists. The intrinsics are not part of that layout (camera_info stays empty).
PhoneRecordingFiles cc9proLayout(const std::string& directory);

// R_cam_imu of the Xiaomi CC9 Pro recording: the proper form of the authors' (wy, wx, wz) axis swap
// (see ../shared/data/cc9pro/README.md and the README's measured figures).
Eigen::Matrix3d cc9proImuToCameraRotation();

struct PhoneRecordingBagOptions {
  std::string image_topic = "/camera/image_raw";
  std::string camera_info_topic = "/camera/camera_info";
  std::string imu_topic = "/imu/data";
  std::string tf_static_topic = "/tf_static";
  std::string lens_shift_topic = "/camera/lens_shift";  // deep_ois/LensShiftSample, with a lens log
  std::string camera_frame_id = "camera_optical_frame";
  std::string imu_frame_id = "imu_link";
  // R_cam_imu: a gyro vector v in the IMU frame is R * v in the camera optical frame.
  Eigen::Matrix3d imu_to_camera_rotation = cc9proImuToCameraRotation();
  // Seconds added to every stamp, gyro and frames alike: moves the recording's clock (a phone's
  // boot clock for cc9pro) to another one, e.g. Unix time. 0 keeps the recording's own stamps.
  double clock_offset_s = 0.0;
  // Seconds added to the frame stamps only, to turn what the recording's stamps mean into the
  // package's convention (stamp = start of readout of the first row). 0 for cc9pro, whose stamps
  // are start-of-frame (SOF) already; e.g. -readout_time for stamps taken at the end of readout.
  double frame_stamp_offset_s = 0.0;
  // Gyro samples kept before the first and after the last frame stamp, seconds (the gyro flow
  // of the first and last pair needs samples around them; a time offset moves that window).
  double imu_margin_s = 0.5;
  // Leave out the frames whose stamp the gyro log does not cover (a gyro started a few ms after the
  // camera, or stopped before it), counted in PhoneRecordingBagStats::dropped_uncovered_frames;
  // false refuses such a recording, naming how many frames lie outside.
  bool drop_uncovered_frames = false;
  // Only the frames from span_from_s to before span_to_s seconds after the recording's first frame
  // (e.g. a training part and a held-out part of one recording); the others are counted in
  // PhoneRecordingBagStats::frames_outside_span.
  double span_from_s = 0.0;
  double span_to_s = std::numeric_limits<double>::infinity();
  rosbag::compression::CompressionType compression = rosbag::compression::LZ4;
};

struct PhoneRecordingBagStats {
  int frames = 0;
  bool images = true;  // false: a recording without images, camera_info alone per frame
  int first_frame_index = 0;
  int last_frame_index = 0;
  int skipped_frame_indices = 0;  // indices between first and last without an image
  int frames_outside_span = 0;  // left out by span_from_s / span_to_s
  int dropped_uncovered_frames = 0;  // images left out: outside the gyro log (drop_uncovered_frames)
  int imu_messages = 0;
  int lens_shift_messages = 0;
  int lens_shift_repeats_dropped = 0;  // repairLensShiftLog: copies of an earlier sample
  int lens_shift_steps_back = 0;       // stamps earlier than the one before, in file order (sorted)
  int width_px = 0;
  int height_px = 0;
  std::string encoding;  // rgb8 or mono8
  ros::Time first_frame_stamp;
  ros::Time last_frame_stamp;
};

// One frame to write.
struct RecordingFrame {
  int index = 0;          // the frame's number in its source (stamp list line, metadata row)
  double stamp_s = 0.0;   // start of readout of the first row, recording clock (offsets not applied)
  std::string label;      // where it comes from, for messages: an image file, "VIDEO frame 12"
};

// A recording in memory, whatever format it came from: what writeRecordingBag writes.
struct RecordingContent {
  std::string gyro_source;  // the file the gyro came from (named in errors)
  std::vector<ImuSample> gyro;  // strictly increasing stamps
  std::string frames_source;
  std::vector<RecordingFrame> frames;  // strictly increasing stamps
  // The image of frames[k], 8-bit mono, BGR or BGRA as OpenCV decodes; called once per frame in
  // increasing k. Empty: a recording without images (camera_info alone per frame).
  std::function<cv::Mat(std::size_t k)> read_image;
  std::string camera_info_source;
  sensor_msgs::CameraInfo camera_info;  // width/height/K of the images as written
  std::string lens_log_source;
  std::vector<LensShiftLogSample> lens_log;  // file order; sorted and cleaned of repeats on writing
  std::vector<int> lens_log_lines;           // 1-based line of each (or empty), for errors
};

// Writes `content` as the bag described below (writePhoneRecordingBag). Throws as it does.
PhoneRecordingBagStats writeRecordingBag(RecordingContent content, const std::string& bag_path,
                                         const PhoneRecordingBagOptions& options,
                                         const std::function<void(int, int)>& progress = nullptr);

// Loads a ROS camera calibration file (YAML or INI). Throws RecordingFormatError naming the file.
sensor_msgs::CameraInfo loadCameraInfoFile(const std::string& path);

// A plumb_bob CameraInfo without distortion for a pinhole camera (pixels).
sensor_msgs::CameraInfo makePinholeCameraInfo(int width_px, int height_px, double fx_px, double fy_px,
                                              double cx_px, double cy_px);

// Writes the bag at `bag_path`, messages in time order, bag time = header stamp:
//  - image_topic: sensor_msgs/Image, mono8 for single-channel images, rgb8 otherwise (alpha
//    dropped); stamp = frame stamp (+ clock and frame offsets), rounded to the nanosecond.
//  - camera_info_topic: the calibration file's CameraInfo, one per image with the image's header.
//  - imu_topic: sensor_msgs/Imu per gyro row inside the frames' span +- imu_margin_s; angular
//    velocity as recorded (IMU frame), orientation covariance[0] = -1 (none), gyro covariance
//    all zero (unknown), no accelerometer (linear_acceleration_covariance[0] = -1).
//  - tf_static_topic: imu_frame_id -> camera_frame_id from imu_to_camera_rotation, latched.
//  - lens_shift_topic (with files.lens_shift_csv): deep_ois/LensShiftSample per row inside the
//    frames' span +- imu_margin_s, stamp + clock_offset_s, values as logged (covariance[0] = -1
//    when the CSV has none); in time order, repeated samples dropped and counted (repairLensShiftLog).
//  - Without images (files.images_dir empty): camera_info alone, one per frame stamp.
// `progress(frames_done, frames_total)` is called after each frame. Throws RecordingFormatError
// naming the file (and line) for malformed or inconsistent inputs: all but the image contents are
// checked before the bag is created; an image that cannot be decoded or does not fit removes the
// partly written bag. std::invalid_argument for bad options; rosbag::BagException when the bag
// cannot be written.
PhoneRecordingBagStats writePhoneRecordingBag(const PhoneRecordingFiles& files, const std::string& bag_path,
                                              const PhoneRecordingBagOptions& options,
                                              const std::function<void(int, int)>& progress = nullptr);

}  // namespace deep_ois
