// Calibrates a camera-IMU pair from a recording: time offset, rolling-shutter readout time, gyro
// bias and IMU-to-camera rotation, from the KLT tracks and the gyro of any hand-held sequence (no
// target). Writes the gyro flow nodelet's parameters and prints the equivalent static transform.
// Flags: --help.
//
// --readout / --time-offset / --rotation hold that quantity at the given value instead of
// estimating it (tf = the bag's /tf_static); --no-bias holds the bias at zero. --ois on removes a
// per-frame lens shift (for cameras with an optical image stabilizer); such a camera needs the
// calibration protocol recording (docs/calibration.md, "Recording (the calibration protocol)": 10 s
// or more of brisk turns about all three axes, roll included, facing a scene 4 m away or more).
// Exit status: 0 written, 1 refused (motion too weak; nothing written) or failed, 2 usage.
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/calibration_yaml.h"
#include "deep_ois/core/calibration/lens_shift_log_calibration.h"
#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

constexpr char kDescription[] =
    "Calibrates a camera-IMU pair from a recording: time offset, rolling-shutter readout time, "
    "gyro bias and IMU-to-camera rotation, from the KLT tracks and the gyro of any hand-held "
    "sequence (no target). Writes the gyro flow nodelet's parameters and prints the equivalent "
    "static transform. --readout / --time-offset / --rotation hold that quantity at the given "
    "value instead of estimating it (tf = the bag's /tf_static); --no-bias holds the bias at zero. "
    "--ois on removes a per-frame lens shift (for cameras with an optical image stabilizer); such "
    "a camera needs the calibration protocol recording (docs/calibration.md, \"Recording (the "
    "calibration protocol)\": 10 s or more of brisk turns about all three axes, roll included, "
    "facing a scene 4 m away or more).";

struct Arguments {
  std::string bag_path, out_path, rotation_text, ois = "off";
  bool quiet = false, no_bias = false, lens_shift = false;
  deep_ois::LensShiftLogCalibrationOptions lens_options;
  deep_ois::CalibrationBagOptions bag_options;
  deep_ois::CalibrationOptions options;
};

void printMatrix(const Eigen::Matrix3d& R) {
  for (int r = 0; r < 3; ++r) {
    std::printf("      [%9.6f %9.6f %9.6f]\n", R(r, 0), R(r, 1), R(r, 2));
  }
}

// Declares the flags, parses them and turns them into the calibration's options; a status to exit
// with when the tool should not go on.
std::optional<int> parseArguments(int argc, char** argv, Arguments* args) {
  deep_ois::CalibrationOptions& options = args->options;
  deep_ois::ToolCommandLine command_line(
      "calibrate", kDescription,
      "Exit status: 0 written, 1 refused (motion too weak; nothing written) or failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--bag", args->bag_path, "the recording")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("IN.bag");
  app.add_option("--out", args->out_path,
                 "the gyro flow nodelet's parameters to write, e.g. config/camera_imu.yaml")
      ->required()
      ->type_name("FILE.yaml");
  app.add_option("--ois", args->ois, "on: remove a per-frame lens shift (OIS cameras)")
      ->check(deep_ois::oneOf({"on", "off"}))
      ->capture_default_str()
      ->type_name("on|off");
  CLI::Option* readout = command_line
                             .addNumber("--readout", options.readout_time_s,
                                        "hold the rolling-shutter readout time at this, seconds")
                             ->type_name("SECONDS");
  readout->default_str("estimated");
  CLI::Option* time_offset =
      command_line
          .addNumber("--time-offset", options.time_offset_s,
                     "hold the time offset at this, seconds (IMU time = camera stamp + offset)")
          ->type_name("SECONDS");
  time_offset->default_str("estimated");
  app.add_option("--rotation", args->rotation_text,
                 "hold R_cam_imu at the bag's /tf_static (tf) or at these 9 row-major numbers "
                 "(default: estimated)")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            return text == "tf" ? std::string() : deep_ois::commaSeparatedNumbers(9)(text);
          },
          ""))
      ->type_name("tf|r00,r01,...,r22");
  app.add_flag("--no-bias", args->no_bias, "hold the gyro bias at zero");
  app.add_flag("--lens-shift", args->lens_shift,
               "also estimate the camera's lens-shift log convention (clock offset, scale, axis "
               "swap, signs) against the images; the bag needs the log (docs/lens_shift_logs.md)");
  command_line
      .addNumber("--lens-shift-max-offset", args->lens_options.max_abs_time_offset_s,
                 "the lens log's clock offset is searched in [-this, +this], seconds")
      ->type_name("SECONDS");
  app.add_option("--lens-shift-topic", args->bag_options.topics.lens_shift_log, "lens-shift log topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  command_line
      .addNumber("--max-offset", options.max_abs_time_offset_s,
                 "the time offset is searched in [-this, +this], seconds")
      ->type_name("SECONDS");
  app.add_option("--image-topic", args->bag_options.topics.image, "image topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--camera-info-topic", args->bag_options.topics.camera_info, "camera_info topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--imu-topic", args->bag_options.topics.imu, "IMU topic (sensor_msgs/Imu)")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_flag("--quiet", args->quiet, "no progress bar");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return status;
  options.lens_shift = args->ois == "on" ? deep_ois::LensShiftHandling::kPerFrameShift
                                         : deep_ois::LensShiftHandling::kNone;
  options.estimate_readout_time = readout->count() == 0;
  options.estimate_time_offset = time_offset->count() == 0;
  options.estimate_gyro_bias = !args->no_bias;
  if (!args->rotation_text.empty()) {
    options.estimate_rotation = false;
    if (args->rotation_text != "tf") {
      const std::vector<double> r = deep_ois::splitCommaSeparatedNumbers(args->rotation_text);
      for (int i = 0; i < 9; ++i) options.imu_to_camera_rotation(i / 3, i % 3) = r[i];
    }
  }
  const std::string problem = options.validate();
  if (!problem.empty()) return command_line.usageError(problem);
  return std::nullopt;
}

// The frames tracked and the gyro, with a progress bar; `reading_s` the time it took.
deep_ois::CalibrationBag readBag(const Arguments& args, double* reading_s) {
  const auto reading_started = std::chrono::steady_clock::now();
  std::unique_ptr<deep_ois::ProgressBar> bar;
  deep_ois::ProgressCallback on_progress;
  if (!args.quiet) {
    on_progress = [&bar](std::size_t done, std::size_t total) {
      if (!bar) bar = std::make_unique<deep_ois::ProgressBar>(total, "pairs tracked");
      bar->update(done);
    };
  }
  deep_ois::CalibrationBag bag = deep_ois::readCalibrationBag(args.bag_path, args.bag_options, on_progress);
  if (!args.quiet) std::fprintf(stderr, "\n");
  *reading_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - reading_started).count();
  return bag;
}

// Only the refusal and the figures that led to it: a refused estimate's values (placeholders when
// the refinement never ran) are not results.
void printRefusal(const Arguments& args, const deep_ois::CalibrationBag& bag,
                  const deep_ois::CalibrationResult& result) {
  std::fprintf(stderr, "calibrate: refused, %s not written:\n", args.out_path.c_str());
  for (const std::string& refusal : result.refusals) std::fprintf(stderr, "  - %s\n", refusal.c_str());
  std::fprintf(stderr, "  figures: %s: %zu frames, %zu frame pairs tracked", args.bag_path.c_str(), bag.frames,
               bag.data.pairs.size());
  if (result.pairs_used > 0) std::fprintf(stderr, ", %d pairs and %d tracks refined", result.pairs_used, result.tracks_used);
  std::fprintf(stderr, "; gyro RMS about its principal axes %.3f %.3f %.3f rad/s",
               result.rate_rms_rad_s(0), result.rate_rms_rad_s(1), result.rate_rms_rad_s(2));
  if (result.median_image_rotation_px > 0.0)
    std::fprintf(stderr, "; median image rotation %.2f px per pair", result.median_image_rotation_px);
  if (result.iterations > 0) {
    std::fprintf(stderr, "; statistical 1-sigma: offset %.3f ms, readout %.3f ms, mount (%.3f %.3f %.3f) deg",
                 result.statistical.time_offset_s * 1e3, result.statistical.readout_time_s * 1e3,
                 result.statistical.rotation_rad(0) * kRadToDeg, result.statistical.rotation_rad(1) * kRadToDeg,
                 result.statistical.rotation_rad(2) * kRadToDeg);
  }
  std::fprintf(stderr, "\n");
  for (const std::string& note : result.notes) std::fprintf(stderr, "  note: %s\n", note.c_str());
}

// The estimate, its 1-sigma and how it was reached.
void printCalibration(const Arguments& args, const deep_ois::CalibrationBag& bag,
                      const deep_ois::CalibrationResult& result, double reading_s) {
  const deep_ois::CalibrationOptions& options = args.options;
  const deep_ois::CameraImuCalibration& c = result.calibration;
  std::printf(
      "calibrate: %s: %zu frames, %d of %zu pairs used, %d tracks; lens shift handling %s\n",
      args.bag_path.c_str(), bag.frames, result.pairs_used, bag.data.pairs.size(), result.tracks_used,
      deep_ois::toString(options.lens_shift));
  std::printf("  gyro RMS about its principal axes: %.3f %.3f %.3f rad/s\n",
              result.rate_rms_rad_s(0), result.rate_rms_rad_s(1), result.rate_rms_rad_s(2));
  std::printf("  coarse stage: time offset %.1f ms, mount %s; median residual %.3f px\n",
              result.coarse_time_offset_s * 1e3,
              result.coarse_permutation_index < 0
                  ? "held"
                  : ("#" + std::to_string(result.coarse_permutation_index)).c_str(),
              result.initial_median_residual_px);
  std::printf("  refined in %d iterations (%s): median residual %.3f px, %.1f %% inliers\n", result.iterations,
              result.converged ? "converged" : "iteration cap reached, NOT converged", result.median_residual_px,
              100.0 * result.inlier_fraction);
  // The 1-sigma printed is the honest one (statistical, inflated, plus the systematic part that
  // every recording shares); the statistical part in brackets is what the refusals judge.
  std::printf("  time offset     %+9.3f ms  +- %.3f ms (statistical %.3f)%s\n", c.time_offset_s * 1e3,
              c.time_offset_sigma_s * 1e3, result.statistical.time_offset_s * 1e3,
              options.estimate_time_offset ? "" : " (held)");
  std::printf("  readout time    %9.3f ms  +- %.3f ms (statistical %.3f)%s\n", c.readout_time_s * 1e3,
              c.readout_time_sigma_s * 1e3, result.statistical.readout_time_s * 1e3,
              options.estimate_readout_time ? "" : " (held)");
  std::printf("  gyro bias       [%+.5f %+.5f %+.5f] rad/s  +- %.5f%s\n", c.gyro_bias_rad_s(0),
              c.gyro_bias_rad_s(1), c.gyro_bias_rad_s(2), c.gyro_bias_sigma_rad_s.maxCoeff(),
              options.estimate_gyro_bias ? "" : " (held)");
  std::printf("  R_cam_imu       +- (%.3f %.3f %.3f) deg about camera x y z (statistical %.3f %.3f %.3f)%s\n",
              c.rotation_sigma_rad(0) * kRadToDeg, c.rotation_sigma_rad(1) * kRadToDeg,
              c.rotation_sigma_rad(2) * kRadToDeg, result.statistical.rotation_rad(0) * kRadToDeg,
              result.statistical.rotation_rad(1) * kRadToDeg, result.statistical.rotation_rad(2) * kRadToDeg,
              options.estimate_rotation ? "" : " (held)");
  // A readout this close to 0 is usually a global shutter, whose readout is known: estimated
  // from a recording with little motion, the offset and readout can slide together along
  // their ridge by a millisecond at a 1-sigma of 0.2-0.3 ms (docs/calibration_uncertainty.md).
  for (const std::string& note : result.notes) std::printf("  note: %s\n", note.c_str());
  printMatrix(c.imu_to_camera_rotation);
  if (result.nearest_permutation_index >= 0) {
    std::printf("  the mount is %.2f deg from the nearest axis permutation (#%d)\n", result.mount_from_permutation_deg,
                result.nearest_permutation_index);
  }
  if (bag.tf_imu_to_camera_rotation) {
    std::printf(
        "  the bag's /tf_static differs by %.3f deg\n",
        deep_ois::rotationAngleBetween(*bag.tf_imu_to_camera_rotation, c.imu_to_camera_rotation) *
            kRadToDeg);
  }
  std::printf("  time: %.2f s reading and tracking (%.2f s KLT), %.2f s estimating\n", reading_s,
              bag.tracking_seconds, result.seconds);
}

// --lens-shift: the log's convention against the images, as YAML lines to append; nothing when
// refused (the refusal printed).
std::optional<std::string> calibrateLensLog(const Arguments& args, const deep_ois::CalibrationBag& bag,
                                            const deep_ois::CameraImuCalibration& c) {
  const deep_ois::LensShiftLogCalibration lens =
      deep_ois::calibrateLensShiftLog(bag.data, c, bag.lens_shift_log, args.lens_options);
  const deep_ois::LensShiftLogConvention& lc = lens.convention;
  std::printf("  lens-shift log (%zu samples on %s): %d row-patch observations, shift differences %.3f px RMS, "
              "residual %.3f px RMS\n",
              bag.lens_shift_log.size(), args.bag_options.topics.lens_shift_log.c_str(), lens.observations,
              lens.lens_motion_rms_px, lens.residual_rms_px);
  if (!lens.ok) {
    std::fprintf(stderr, "calibrate: refused, %s not written: lens-shift log: %s\n", args.out_path.c_str(),
                 lens.problem.c_str());
    return std::nullopt;
  }
  std::printf("    time offset %+.3f ms (camera = log stamp + it), scale %.4f, swap_xy %s, signs %+g %+g "
              "(free fit off this form by %.1f %%)\n",
              lc.time_offset_s * 1e3, lc.scale, lc.swap_xy ? "true" : "false", lc.sign_x, lc.sign_y,
              100.0 * lens.snap_error);
  std::ostringstream yaml;
  yaml << std::setprecision(9) << "# The camera's lens-shift log convention, estimated against the images ("
       << lens.observations << " row-patch observations, residual " << std::setprecision(3)
       << lens.residual_rms_px << " px RMS).\n"
       << std::setprecision(9) << "lens_shift_scale: " << lc.scale << "\nlens_shift_swap_xy: "
       << (lc.swap_xy ? "true" : "false") << "\nlens_shift_sign_x: " << lc.sign_x
       << ".0\nlens_shift_sign_y: " << lc.sign_y << ".0\nlens_shift_time_offset: " << lc.time_offset_s << "\n";
  return yaml.str();
}

// The gyro flow parameters file, and the static transform that says the same mount.
void writeCalibration(const Arguments& args, const deep_ois::CalibrationBag& bag,
                      const deep_ois::CalibrationResult& result, const std::string& lens_yaml) {
  deep_ois::CalibrationProvenance provenance;
  provenance.source = args.bag_path;
  provenance.imu_frame_id = bag.imu_frame_id;
  provenance.camera_frame_id = bag.camera_frame_id;
  provenance.lens_shift = args.options.lens_shift;
  deep_ois::writeTextFile(args.out_path, deep_ois::calibrationYaml(result, provenance) + lens_yaml);
  std::printf("wrote %s\nequivalent static transform:\n  %s\n", args.out_path.c_str(),
              deep_ois::staticTransformCommand(result.calibration.imu_to_camera_rotation, bag.imu_frame_id,
                                               bag.camera_frame_id)
                  .c_str());
}

}  // namespace

int main(int argc, char** argv) {
  Arguments args;
  if (const std::optional<int> status = parseArguments(argc, argv, &args)) return *status;
  try {
    double reading_s = 0.0;
    const deep_ois::CalibrationBag bag = readBag(args, &reading_s);
    if (args.rotation_text == "tf") {
      if (!bag.tf_imu_to_camera_rotation) {
        std::fprintf(stderr, "calibrate: --rotation tf, but %s: %s\n", args.bag_path.c_str(), bag.tf_problem.c_str());
        return 1;
      }
      args.options.imu_to_camera_rotation = *bag.tf_imu_to_camera_rotation;
    }
    const deep_ois::CalibrationResult result = deep_ois::calibrateCameraImu(bag.data, args.options);
    if (!result.ok()) {
      printRefusal(args, bag, result);
      return 1;
    }
    printCalibration(args, bag, result, reading_s);
    std::string lens_yaml;
    if (args.lens_shift) {
      const std::optional<std::string> lens = calibrateLensLog(args, bag, result.calibration);
      if (!lens) return 1;
      lens_yaml = *lens;
    }
    writeCalibration(args, bag, result, lens_yaml);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate: %s\n", e.what());
    return 1;
  }
}
