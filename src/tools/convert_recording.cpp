// Converts a phone recording (gyro CSV + frame stamp list + frame images + intrinsics, the layout
// of ../shared/data/cc9pro) into the rosbag a robot would have recorded, for the nodelets and the
// evaluator.
//
//   convert_recording --recording DIR --camera-info FILE.yaml --out FILE.bag [options]
//
// Run without arguments for the options. The work is done by writePhoneRecordingBag
// (deep_ois/ros/bag/phone_recording_bag.h), which documents what the bag holds.
#include <rosbag/bag.h>

#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"

namespace {

const char kUsage[] =
    "usage: convert_recording --recording DIR --camera-info FILE --out FILE.bag [options]\n"
    "  --recording DIR          folder in the cc9pro layout: gyro.txt (rows wx,wy,wz,t in rad/s and s),\n"
    "                           framestamp.txt (line i = stamp of frame i, s), frames/ (images whose\n"
    "                           name ends in the frame index, e.g. RE_frame-99.jpg)\n"
    "  --gyro FILE, --frame-stamps FILE, --images DIR   override one part of that layout (all three\n"
    "                           are required without --recording)\n"
    "  --camera-info FILE       ROS camera calibration (YAML/INI as written by camera_calibration),\n"
    "                           e.g. config/cameras/cc9pro.yaml\n"
    "  --out FILE.bag           output bag\n"
    "  --imu-to-camera R        R_cam_imu, 9 comma-separated row-major values (default: the cc9pro's\n"
    "                           0,-1,0,-1,0,0,0,0,-1)\n"
    "  --image-topic T (/camera/image_raw)  --camera-info-topic T (/camera/camera_info)\n"
    "  --imu-topic T (/imu/data)  --tf-static-topic T (/tf_static)\n"
    "  --camera-frame F (camera_optical_frame)  --imu-frame F (imu_link)\n"
    "  --clock-offset S         seconds added to every stamp (gyro and frames), e.g. boot clock -> Unix\n"
    "                           time (default 0: the recording's own clock)\n"
    "  --frame-stamp-offset S   seconds added to the frame stamps only, so that they mean the start of\n"
    "                           readout of the first row (default 0: cc9pro stamps are start of frame)\n"
    "  --imu-margin S           gyro kept before the first and after the last frame (default 0.5)\n"
    "  --drop-uncovered-frames  leave out (and count) the frames the gyro log does not cover, instead\n"
    "                           of refusing the recording\n"
    "  --compression lz4|bz2|none (default lz4)   --quiet (no progress bar)\n";

int usage(const std::string& problem) {
  std::fprintf(stderr, "convert_recording: %s\n%s", problem.c_str(), kUsage);
  return 2;
}

double parseSeconds(const std::string& flag, const std::string& value) {
  std::size_t used = 0;
  const double seconds = std::stod(value, &used);
  if (used != value.size()) throw std::invalid_argument(flag);
  return seconds;
}

Eigen::Matrix3d parseRotation(const std::string& value) {
  std::vector<double> values;
  std::stringstream in(value);
  std::string field;
  while (std::getline(in, field, ',')) {
    std::size_t used = 0;
    values.push_back(std::stod(field, &used));
    while (used < field.size() && field[used] == ' ') ++used;
    if (used != field.size()) throw std::invalid_argument(field);
  }
  if (values.size() != 9) throw std::invalid_argument(value);
  Eigen::Matrix3d R;
  for (int k = 0; k < 9; ++k) R(k / 3, k % 3) = values[k];
  return R;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 1) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  deep_ois::PhoneRecordingFiles files;
  deep_ois::PhoneRecordingBagOptions options;
  std::string recording, gyro, frame_stamps, images, out;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--drop-uncovered-frames") {
      options.drop_uncovered_frames = true;
      continue;
    }
    if (flag == "--quiet") {
      quiet = true;
      continue;
    }
    if (i + 1 >= argc) return usage("flag " + flag + " needs a value");
    const std::string value = argv[++i];
    try {
      if (flag == "--recording") recording = value;
      else if (flag == "--gyro") gyro = value;
      else if (flag == "--frame-stamps") frame_stamps = value;
      else if (flag == "--images") images = value;
      else if (flag == "--camera-info") files.camera_info = value;
      else if (flag == "--out") out = value;
      else if (flag == "--imu-to-camera") options.imu_to_camera_rotation = parseRotation(value);
      else if (flag == "--image-topic") options.image_topic = value;
      else if (flag == "--camera-info-topic") options.camera_info_topic = value;
      else if (flag == "--imu-topic") options.imu_topic = value;
      else if (flag == "--tf-static-topic") options.tf_static_topic = value;
      else if (flag == "--camera-frame") options.camera_frame_id = value;
      else if (flag == "--imu-frame") options.imu_frame_id = value;
      else if (flag == "--clock-offset") options.clock_offset_s = parseSeconds(flag, value);
      else if (flag == "--frame-stamp-offset") options.frame_stamp_offset_s = parseSeconds(flag, value);
      else if (flag == "--imu-margin") options.imu_margin_s = parseSeconds(flag, value);
      else if (flag == "--compression") {
        if (value == "lz4") options.compression = rosbag::compression::LZ4;
        else if (value == "bz2") options.compression = rosbag::compression::BZ2;
        else if (value == "none") options.compression = rosbag::compression::Uncompressed;
        else return usage("--compression must be lz4, bz2 or none, got '" + value + "'");
      } else {
        return usage("unknown flag " + flag);
      }
    } catch (const std::logic_error&) {
      if (flag == "--imu-to-camera") return usage("--imu-to-camera needs 9 comma-separated numbers, got '" + value + "'");
      return usage("flag " + flag + " needs a number of seconds, got '" + value + "'");
    }
  }
  if (!recording.empty()) {
    const deep_ois::PhoneRecordingFiles layout = deep_ois::cc9proLayout(recording);
    files.gyro_csv = layout.gyro_csv;
    files.frame_stamps = layout.frame_stamps;
    files.images_dir = layout.images_dir;
  }
  if (!gyro.empty()) files.gyro_csv = gyro;
  if (!frame_stamps.empty()) files.frame_stamps = frame_stamps;
  if (!images.empty()) files.images_dir = images;
  if (files.gyro_csv.empty() || files.frame_stamps.empty() || files.images_dir.empty()) {
    return usage("give --recording DIR, or all of --gyro, --frame-stamps and --images");
  }
  if (files.camera_info.empty()) return usage("--camera-info is required (a ROS camera calibration file)");
  if (out.empty()) return usage("--out is required");

  try {
    std::unique_ptr<deep_ois::ProgressBar> bar;
    auto progress = [&](int done, int total) {
      if (quiet) return;
      if (!bar) bar = std::make_unique<deep_ois::ProgressBar>(static_cast<std::size_t>(total), "frames");
      bar->update(static_cast<std::size_t>(done));
    };
    const deep_ois::PhoneRecordingBagStats stats =
        deep_ois::writePhoneRecordingBag(files, out, options, progress);
    std::printf("convert_recording: %s: %d frames (indices %d..%d, %d missing) %dx%d %s, stamps %u.%09u .. %u.%09u s, "
                "%d IMU messages, %.1f s%s\n",
                out.c_str(), stats.frames, stats.first_frame_index, stats.last_frame_index,
                stats.skipped_frame_indices, stats.width_px, stats.height_px, stats.encoding.c_str(),
                stats.first_frame_stamp.sec, stats.first_frame_stamp.nsec,
                stats.last_frame_stamp.sec, stats.last_frame_stamp.nsec, stats.imu_messages,
                bar ? bar->elapsedSeconds() : 0.0,
                stats.dropped_uncovered_frames > 0
                    ? ("; dropped " + std::to_string(stats.dropped_uncovered_frames) +
                       " frames the gyro does not cover").c_str()
                    : "");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "convert_recording: %s\n", e.what());
    return 1;
  }
}
