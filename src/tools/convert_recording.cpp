// Converts a phone recording (gyro CSV + frame stamp list + frame images + intrinsics, the layout
// of ../shared/data/cc9pro) into the rosbag a robot would have recorded, for the nodelets and the
// evaluator.
//
// Flags: --help (run without arguments, it prints them too). The work is done by
// writePhoneRecordingBag (deep_ois/ros/bag/phone_recording_bag.h), which documents what the bag
// holds.
#include <rosbag/bag.h>

#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"

constexpr char kDescription[] =
    "Converts a phone recording (gyro CSV + frame stamp list + frame images + intrinsics, the "
    "layout "
    "of ../shared/data/cc9pro) into the rosbag a robot would have recorded (image, camera_info, "
    "IMU "
    "and /tf_static topics), for the nodelets and the evaluator.";

int main(int argc, char** argv) {
  deep_ois::PhoneRecordingFiles files;
  deep_ois::PhoneRecordingBagOptions options;
  std::string recording, gyro, frame_stamps, images, out, imu_to_camera, compression = "lz4";
  bool quiet = false;
  deep_ois::ToolCommandLine command_line("convert_recording", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option(
         "--recording", recording,
         "folder in the cc9pro layout: gyro.txt (rows wx,wy,wz,t in rad/s and s), "
         "framestamp.txt (line i = stamp of frame i, s), frames/ (images whose name ends in "
         "the frame index, e.g. RE_frame-99.jpg)")
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  app.add_option("--gyro", gyro,
                 "override the gyro CSV of the layout (all three are required without --recording)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--frame-stamps", frame_stamps, "override the frame stamp list of the layout")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--lens-shift", files.lens_shift_csv,
                 "the camera's lens-shift log, rows t,x,y[,cxx,cxy,cyy] (s on the frames' clock, "
                 "shift as logged; docs/lens_shift_logs.md); default: lens_shift.txt of the layout "
                 "when present")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--lens-shift-topic", options.lens_shift_topic, "lens-shift log topic (deep_ois/LensShiftSample)")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--images", images, "override the image folder of the layout")
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  app.add_option("--camera-info", files.camera_info,
                 "ROS camera calibration (YAML/INI as written by camera_calibration), e.g. "
                 "config/cameras/cc9pro.yaml")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--out", out, "output bag")->required()->type_name("FILE.bag");
  app.add_option("--imu-to-camera", imu_to_camera,
                 "R_cam_imu, 9 comma-separated row-major values (default: the cc9pro's "
                 "0,-1,0,-1,0,0,0,0,-1)")
      ->check(deep_ois::commaSeparatedNumbers(9))
      ->type_name("R");
  app.add_option("--image-topic", options.image_topic, "image topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--camera-info-topic", options.camera_info_topic, "camera_info topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--imu-topic", options.imu_topic, "IMU topic (sensor_msgs/Imu)")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--tf-static-topic", options.tf_static_topic, "static transform topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--camera-frame", options.camera_frame_id, "frame id of the camera (optical)")
      ->capture_default_str()
      ->type_name("FRAME");
  app.add_option("--imu-frame", options.imu_frame_id, "frame id of the IMU")
      ->capture_default_str()
      ->type_name("FRAME");
  command_line
      .addNumber("--clock-offset", options.clock_offset_s,
                 "seconds added to every stamp (gyro and frames), e.g. boot clock -> Unix time "
                 "(0: the recording's own clock)")
      ->type_name("SECONDS");
  command_line
      .addNumber("--frame-stamp-offset", options.frame_stamp_offset_s,
                 "seconds added to the frame stamps only, so that they mean the start of "
                 "readout of the first row (0: cc9pro stamps are start of frame)")
      ->type_name("SECONDS");
  command_line
      .addNumber("--imu-margin", options.imu_margin_s,
                 "gyro kept before the first and after the last frame, seconds")
      ->type_name("SECONDS");
  app.add_option("--compression", compression, "bag compression")
      ->check(deep_ois::oneOf({"lz4", "bz2", "none"}))
      ->capture_default_str()
      ->type_name("lz4|bz2|none");
  app.add_flag("--quiet", quiet, "no progress bar");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (!imu_to_camera.empty()) {
    const std::vector<double> r = deep_ois::splitCommaSeparatedNumbers(imu_to_camera);
    for (int k = 0; k < 9; ++k) options.imu_to_camera_rotation(k / 3, k % 3) = r[k];
  }
  options.compression = compression == "lz4"   ? rosbag::compression::LZ4
                        : compression == "bz2" ? rosbag::compression::BZ2
                                               : rosbag::compression::Uncompressed;
  if (!recording.empty()) {
    const deep_ois::PhoneRecordingFiles layout = deep_ois::cc9proLayout(recording);
    files.gyro_csv = layout.gyro_csv;
    files.frame_stamps = layout.frame_stamps;
    files.images_dir = layout.images_dir;
    if (files.lens_shift_csv.empty()) files.lens_shift_csv = layout.lens_shift_csv;
  }
  if (!gyro.empty()) files.gyro_csv = gyro;
  if (!frame_stamps.empty()) files.frame_stamps = frame_stamps;
  if (!images.empty()) files.images_dir = images;
  if (files.gyro_csv.empty() || files.frame_stamps.empty() || files.images_dir.empty()) {
    return command_line.usageError(
        "give --recording DIR, or all of --gyro, --frame-stamps and --images");
  }

  try {
    std::unique_ptr<deep_ois::ProgressBar> bar;
    auto progress = [&](int done, int total) {
      if (quiet) return;
      if (!bar)
        bar = std::make_unique<deep_ois::ProgressBar>(static_cast<std::size_t>(total), "frames");
      bar->update(static_cast<std::size_t>(done));
    };
    const deep_ois::PhoneRecordingBagStats stats =
        deep_ois::writePhoneRecordingBag(files, out, options, progress);
    std::printf(
        "convert_recording: %s: %d frames (indices %d..%d, %d missing) %dx%d %s, stamps %u.%09u .. "
        "%u.%09u s, %d IMU messages, %d lens-shift samples, %.1f s%s\n",
        out.c_str(), stats.frames, stats.first_frame_index, stats.last_frame_index,
        stats.skipped_frame_indices, stats.width_px, stats.height_px, stats.encoding.c_str(),
        stats.first_frame_stamp.sec, stats.first_frame_stamp.nsec, stats.last_frame_stamp.sec,
        stats.last_frame_stamp.nsec, stats.imu_messages, stats.lens_shift_messages, bar ? bar->elapsedSeconds() : 0.0,
        stats.dropped_uncovered_frames > 0
            ? ("; dropped " + std::to_string(stats.dropped_uncovered_frames) +
               " frames the gyro does not cover")
                  .c_str()
            : "");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "convert_recording: %s\n", e.what());
    return 1;
  }
}
