// Converts a phone recording into the rosbag a robot would have recorded, for the nodelets, the
// calibration, training and the evaluator. Formats: the folder layout of ../shared/data/cc9pro
// (gyro CSV + frame stamp list + frame images + intrinsics), VideoIMUCapture (video +
// video_meta.pb3) and Google's DVS logs (text logs, no video).
//
// Flags: --help (run without arguments, it prints them too). One writer for all formats:
// writeRecordingBag (deep_ois/ros/bag/phone_recording_bag.h), which documents what the bag holds;
// the importers are in deep_ois/ros/bag/phone_logger_import.h.
#include <rosbag/bag.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/calibration_yaml.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/ros/bag/phone_logger_import.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/tools/support/recording_conversion_report.h"

namespace {

constexpr char kDescription[] =
    "Converts a phone recording into the rosbag a robot would have recorded (image, camera_info, "
    "IMU, /tf_static and lens-shift topics): the folder layout of ../shared/data/cc9pro, "
    "VideoIMUCapture (video + video_meta.pb3) or Google's DVS logs (docs/real_recordings.md). For "
    "the phone formats it also writes the gyro flow parameters the metadata gives (readout, mount, "
    "lens-log convention) beside the bag.";

// What --recording DIR may hold, one layout per --format.
constexpr char kRecordingHelp[] =
    "the recording's folder, in one of three layouts (--format; auto: told by its files): "
    "'folder', the cc9pro layout: gyro.txt (rows wx,wy,wz,t in rad/s and s), framestamp.txt (line "
    "i = stamp of frame i, s), frames/ (optional: images whose name ends in the frame index, e.g. "
    "RE_frame-99.jpg; without it camera_info only) and lens_shift.txt (optional lens log), with "
    "--camera-info; 'videoimucapture', the VideoIMUCapture Android app's: a video (.mp4, .mkv or "
    ".mov; HEVC or H.264) and video_meta.pb3; 'dvs', Google's DVS logs (no video): "
    "frame_timestamps_*.txt, gyro_log_*.txt, ois_log_*.txt and calib.txt (optional)";

namespace fs = std::filesystem;

struct Arguments {
  deep_ois::PhoneRecordingFiles files;
  deep_ois::PhoneRecordingBagOptions options;
  std::string recording, gyro, frame_stamps, images, out, imu_to_camera, compression = "lz4";
  std::string format = "auto", video, metadata, gyro_config_out, image_size = "1920x1080";
  bool quiet = false, without_images = false;
  deep_ois::VideoImportOptions video_options;
  deep_ois::DvsImportOptions dvs_options;
  int frame_shift = 0;
};

// The one file in `directory` whose name ends in one of `suffixes` ("" when none); throws when
// several do.
std::string findBySuffix(const std::string& directory, std::initializer_list<const char*> suffixes) {
  std::string found;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory)) {
    const std::string name = entry.path().filename().string();
    for (const char* suffix : suffixes) {
      const std::string s(suffix);
      if (name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) {
        if (!found.empty()) {
          throw deep_ois::RecordingFormatError(directory, 0, "two candidates: " + found + " and " + entry.path().string());
        }
        found = entry.path().string();
      }
    }
  }
  return found;
}

// What --recording DIR holds: a VideoIMUCapture recording (a .pb3 or a video), DVS logs or the
// folder layout.
std::string detectFormat(const std::string& directory) {
  if (!findBySuffix(directory, {".pb3"}).empty() || !findBySuffix(directory, {".mp4", ".MP4", ".mkv", ".mov"}).empty())
    return "videoimucapture";
  for (const fs::directory_entry& entry : fs::directory_iterator(directory))
    if (entry.path().filename().string().rfind("frame_timestamps_", 0) == 0) return "dvs";
  return "folder";
}

void declareFlags(deep_ois::ToolCommandLine& command_line, Arguments* args) {
  CLI::App& app = command_line.app();
  deep_ois::PhoneRecordingBagOptions& options = args->options;
  app.add_option("--recording", args->recording, kRecordingHelp)
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  app.add_option("--gyro", args->gyro,
                 "override the gyro CSV of the layout (all three are required without --recording)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--frame-stamps", args->frame_stamps, "override the frame stamp list of the layout")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--lens-shift", args->files.lens_shift_csv,
                 "the camera's lens-shift log, rows t,x,y[,cxx,cxy,cyy] (s on the frames' clock, "
                 "shift as logged; docs/lens_shift_logs.md); default: lens_shift.txt of the layout "
                 "when present")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--lens-shift-topic", options.lens_shift_topic, "lens-shift log topic (deep_ois/LensShiftSample)")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--images", args->images, "override the image folder of the layout")
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  app.add_option("--camera-info", args->files.camera_info,
                 "ROS camera calibration (YAML/INI as written by camera_calibration), e.g. "
                 "config/cameras/cc9pro.yaml")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--out", args->out, "output bag")->required()->type_name("FILE.bag");
  app.add_option("--format", args->format,
                 "what --recording holds: 'folder' (the cc9pro layout; needs --camera-info), "
                 "'videoimucapture' (a video + video_meta.pb3), 'dvs' (Google's DVS text logs) or "
                 "'auto' (from the files in it)")
      ->check(deep_ois::oneOf({"auto", "folder", "videoimucapture", "dvs"}))
      ->capture_default_str();
  app.add_option("--video", args->video, "VideoIMUCapture: the video (HEVC/H.264); default: the one in --recording")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--metadata", args->metadata, "VideoIMUCapture: video_meta.pb3; default: the one in --recording")
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_flag("--without-images", args->without_images,
               "write no images: camera_info per frame stamp, gyro, lens log (for train_stabiliser "
               "--target log). The folder layout without frames/ (or without --images) is converted so "
               "too");
  app.add_flag("--drop-uncovered-frames", options.drop_uncovered_frames,
               "leave out (and count) the frames whose stamp the gyro does not cover, e.g. a gyro that "
               "starts a few ms after the first frame; without it such a recording is refused");
  command_line.addNumber("--from", options.span_from_s,
                         "keep the frames from this many seconds after the first frame (e.g. a held-out part)")
      ->type_name("SECONDS");
  command_line.addNumber("--to", options.span_to_s,
                         "keep the frames before this many seconds after the first frame")
      ->type_name("SECONDS");
  app.add_option("--gyro-config-out", args->gyro_config_out,
                 "videoimucapture/dvs: where to write the gyro flow parameters the metadata gives "
                 "(default: OUT with .gyro_flow.yaml in place of .bag)")
      ->type_name("FILE.yaml");
  command_line.addNumber("--image-scale", args->video_options.image_scale,
                         "videoimucapture: scale the frames (and intrinsics) by this, 0 < s <= 1")
      ->capture_default_str();
  app.add_flag("--grey", args->video_options.grey, "videoimucapture: write mono8 frames (calibrate reads grey)");
  command_line.addNumber("--max-frames", args->video_options.max_frames,
                         "videoimucapture: the first N video frames only (0: all)")
      ->capture_default_str();
  command_line.addNumber("--frame-shift", args->frame_shift,
                         "videoimucapture: video frame j is metadata row j - N, in place of a pairing the "
                         "gyro check does not confirm (the found pairing and its confidence are printed)");
  app.add_option("--image-size", args->image_size,
                 "dvs: the image size the camera_info describes (the logs have no video)")
      ->capture_default_str()
      ->type_name("WxH");
  command_line.addNumber("--active-array-width", args->dvs_options.active_array_width_px,
                         "dvs: the sensor's active-array width, px (the OIS log's unit; Pixel 4: 4032)")
      ->capture_default_str();

  app.add_option("--imu-to-camera", args->imu_to_camera,
                 "R_cam_imu, 9 comma-separated row-major values (default: folder layout the cc9pro's "
                 "0,-1,0,-1,0,0,0,0,-1; videoimucapture the Android back camera's for its "
                 "SENSOR_ORIENTATION; dvs -1,0,0,0,1,0,0,0,-1)")
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
  app.add_option("--compression", args->compression, "bag compression")
      ->check(deep_ois::oneOf({"lz4", "bz2", "none"}))
      ->capture_default_str()
      ->type_name("lz4|bz2|none");
  app.add_flag("--quiet", args->quiet, "no progress bar");
}

// The flags as the importers and the writer take them, the format told and the files of its
// layout checked; a status to exit with when the tool should not go on.
std::optional<int> parseArguments(int argc, char** argv, Arguments* args) {
  deep_ois::ToolCommandLine command_line("convert_recording", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage.");
  declareFlags(command_line, args);
  if (const std::optional<int> status = command_line.parse(argc, argv)) return status;
  deep_ois::PhoneRecordingBagOptions& options = args->options;
  if (!args->imu_to_camera.empty()) {
    const std::vector<double> r = deep_ois::splitCommaSeparatedNumbers(args->imu_to_camera);
    for (int k = 0; k < 9; ++k) options.imu_to_camera_rotation(k / 3, k % 3) = r[k];
  }
  options.compression = args->compression == "lz4"   ? rosbag::compression::LZ4
                        : args->compression == "bz2" ? rosbag::compression::BZ2
                                                     : rosbag::compression::Uncompressed;
  if (args->frame_shift != 0 || command_line.app().count("--frame-shift") > 0)
    args->video_options.forced_shift = args->frame_shift;
  args->video_options.without_images = args->without_images;
  if (args->gyro_config_out.empty()) {
    const std::string& out = args->out;
    args->gyro_config_out =
        out.size() > 4 && out.compare(out.size() - 4, 4, ".bag") == 0 ? out.substr(0, out.size() - 4) : out;
    args->gyro_config_out += ".gyro_flow.yaml";
  }
  try {
    if (args->format == "auto")
      args->format = !args->video.empty() || !args->metadata.empty() ? "videoimucapture"
                     : args->recording.empty()                        ? "folder"
                                                                      : detectFormat(args->recording);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "convert_recording: %s\n", e.what());
    return 1;
  }
  deep_ois::PhoneRecordingFiles& files = args->files;
  if (args->format == "folder") {
    if (!args->recording.empty()) {
      const deep_ois::PhoneRecordingFiles layout = deep_ois::cc9proLayout(args->recording);
      files.gyro_csv = layout.gyro_csv;
      files.frame_stamps = layout.frame_stamps;
      files.images_dir = layout.images_dir;
      if (files.lens_shift_csv.empty()) files.lens_shift_csv = layout.lens_shift_csv;
    }
    if (!args->gyro.empty()) files.gyro_csv = args->gyro;
    if (!args->frame_stamps.empty()) files.frame_stamps = args->frame_stamps;
    if (!args->images.empty()) files.images_dir = args->images;
    if (args->without_images) files.images_dir.clear();
    if (files.gyro_csv.empty() || files.frame_stamps.empty())
      return command_line.usageError("give --recording DIR, or --gyro and --frame-stamps (and --images)");
    if (files.camera_info.empty()) return command_line.usageError("the folder layout needs --camera-info FILE");
  } else if (args->format == "dvs") {
    if (args->recording.empty()) return command_line.usageError("--format dvs needs --recording DIR (the log folder)");
    deep_ois::DvsImportOptions& dvs = args->dvs_options;
    const std::size_t x = args->image_size.find('x');
    try {
      if (x == std::string::npos) throw std::invalid_argument(args->image_size);
      dvs.image_width_px = std::stoi(args->image_size.substr(0, x));
      dvs.image_height_px = std::stoi(args->image_size.substr(x + 1));
    } catch (const std::exception&) {
      return command_line.usageError("--image-size: expected WxH, e.g. 1920x1080, got '" + args->image_size + "'");
    }
    if (dvs.image_width_px <= 0 || dvs.image_height_px <= 0)
      return command_line.usageError("--image-size: width and height must be positive");
  } else if (args->format == "videoimucapture") {
    try {
      if (!args->recording.empty()) {
        if (args->metadata.empty()) args->metadata = findBySuffix(args->recording, {".pb3"});
        if (args->video.empty()) args->video = findBySuffix(args->recording, {".mp4", ".MP4", ".mkv", ".mov"});
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "convert_recording: %s\n", e.what());
      return 1;
    }
    if (args->video.empty() && args->metadata.empty())
      return command_line.usageError("videoimucapture: give --recording DIR or --video and --metadata");
    if (args->without_images) args->video.clear();
  }
  return std::nullopt;
}

// A phone logger's recording read into memory (nothing for the folder layout, which the writer
// reads itself), its notes and the mount it takes printed.
std::optional<deep_ois::ImportedRecording> importRecording(Arguments& args) {
  std::optional<deep_ois::ImportedRecording> imported;
  if (args.format == "videoimucapture") {
    args.video_options.progress_note = [&args](const std::string& note) {
      if (!args.quiet) std::fprintf(stderr, "convert_recording: %s\n", note.c_str());
    };
    imported = deep_ois::importVideoImuCapture(args.video, args.metadata, args.video_options);
  } else if (args.format == "dvs") {
    imported = deep_ois::importDvsLogs(args.recording, args.dvs_options);
  }
  if (!imported) return imported;
  // The logger's mount unless the user gives one.
  if (args.imu_to_camera.empty()) args.options.imu_to_camera_rotation = imported->imu_to_camera_rotation;
  else imported->imu_to_camera_rotation = args.options.imu_to_camera_rotation;
  for (const std::string& note : imported->notes) std::printf("convert_recording: %s\n", note.c_str());
  std::printf("convert_recording: IMU-to-camera rotation: %s\n",
              args.imu_to_camera.empty() ? imported->imu_to_camera_source.c_str() : "--imu-to-camera");
  return imported;
}

// The bag (and, for a phone logger, the gyro flow parameters beside it).
deep_ois::PhoneRecordingBagStats writeOutputs(const Arguments& args,
                                              std::optional<deep_ois::ImportedRecording> imported) {
  std::unique_ptr<deep_ois::ProgressBar> bar;
  auto progress = [&](int done, int total) {
    if (args.quiet) return;
    if (!bar) bar = std::make_unique<deep_ois::ProgressBar>(static_cast<std::size_t>(total), "frames");
    bar->update(static_cast<std::size_t>(done));
  };
  const std::string gyro_yaml = imported ? deep_ois::importedGyroFlowYaml(*imported, args.out) : "";
  const deep_ois::PhoneRecordingBagStats stats =
      imported ? deep_ois::writeRecordingBag(std::move(imported->content), args.out, args.options, progress)
               : deep_ois::writePhoneRecordingBag(args.files, args.out, args.options, progress);
  if (imported) {
    deep_ois::writeTextFile(args.gyro_config_out, gyro_yaml);
    std::printf("convert_recording: gyro flow parameters (readout %.3f ms, mount, lens-log convention): %s\n",
                imported->readout_s * 1e3, args.gyro_config_out.c_str());
  }
  return stats;
}

}  // namespace

int main(int argc, char** argv) {
  Arguments args;
  if (const std::optional<int> status = parseArguments(argc, argv, &args)) return *status;
  try {
    const auto started = std::chrono::steady_clock::now();
    std::optional<deep_ois::ImportedRecording> imported = importRecording(args);
    const deep_ois::PhoneRecordingBagStats stats = writeOutputs(args, std::move(imported));
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    for (const std::string& line : deep_ois::conversionSummary(args.out, stats, wall_s))
      std::printf("convert_recording: %s\n", line.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fflush(stdout);  // what was said before the error comes first
    std::fprintf(stderr, "convert_recording: %s\n", e.what());
    return 1;
  }
}
