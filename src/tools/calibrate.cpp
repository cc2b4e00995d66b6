// Calibrates a camera-IMU pair from a recording: time offset, rolling-shutter readout time, gyro
// bias and IMU-to-camera rotation, from the KLT tracks and the gyro of any hand-held sequence (no
// target). Writes the gyro flow nodelet's parameters and prints the equivalent static transform.
// Flags: --help.
//
// --readout / --time-offset / --rotation hold that quantity at the given value instead of
// estimating it (tf = the bag's /tf_static); --no-bias holds the bias at zero. The recording's
// gyro flow parameters (--gyro-config; by default the OUT.gyro_flow.yaml convert_recording writes
// beside the bag) give the logged readout, the mount and the bias as priors: each is held, with its
// 1-sigma, only when the recording cannot determine it (core/calibration/calibration_priors.h). --ois on removes a
// per-frame lens shift (for cameras with an optical image stabilizer); such a camera needs the
// calibration protocol recording (docs/calibration.md, "Recording (the calibration protocol)": 10 s
// or more of brisk turns about all three axes, roll included, facing a scene 4 m away or more).
// Exit status: 0 written, 1 refused (motion too weak; nothing written) or failed, 2 usage.
#include <Eigen/Geometry>
#include <chrono>
#include <fstream>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/calibration_priors.h"
#include "deep_ois/core/calibration/calibration_yaml.h"
#include "deep_ois/core/calibration/lens_shift_log_calibration.h"
#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/ros/live/parameter_source.h"
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
    "The recording's gyro flow parameters (--gyro-config, by default the OUT.gyro_flow.yaml that "
    "convert_recording writes beside the bag) give the logged readout, the mount and the gyro bias "
    "as priors: each is held at its stated value only when the recording cannot determine it, and "
    "the output says which values came from that file and which from the data. "
    "--ois on removes a per-frame lens shift (for cameras with an optical image stabilizer); such "
    "a camera needs the calibration protocol recording (docs/calibration.md, \"Recording (the "
    "calibration protocol)\": 10 s or more of brisk turns about all three axes, roll included, "
    "facing a scene 4 m away or more).";

struct Arguments {
  std::string bag_path, out_path, rotation_text, ois = "off";
  // --gyro-config as given ("none" = no priors), and the file the priors are read from (with
  // "none", the file beside the bag, read only to name its values in a refusal's remedy).
  std::string gyro_config, gyro_config_used;
  bool apply_priors = true;
  double prior_mount_sigma_deg = 1.0;
  deep_ois::CalibrationPriors priors;
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
  app.add_option("--gyro-config", args->gyro_config,
                 "the recording's gyro flow parameters (readout_time, imu_to_camera_rotation, gyro_bias): "
                 "priors, held only when the recording cannot determine them; none = no priors")
      ->default_str("IN.gyro_flow.yaml beside the bag, when it exists")
      ->type_name("FILE|none");
  command_line
      .addNumber("--prior-readout-sigma", args->priors.readout_time_sigma_s,
                 "1-sigma of the gyro config's readout, seconds (default: the readout's acceptance limit)")
      ->type_name("SECONDS");
  command_line
      .addNumber("--prior-mount-sigma", args->prior_mount_sigma_deg,
                 "1-sigma of the gyro config's mount per camera axis, degrees")
      ->capture_default_str()
      ->type_name("DEGREES");
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
  args->priors.rotation_sigma_rad = args->prior_mount_sigma_deg / kRadToDeg;
  args->apply_priors = args->gyro_config != "none";
  if (args->gyro_config.empty() || args->gyro_config == "none") {
    const std::string& bag = args->bag_path;
    const std::string beside =
        (bag.size() > 4 && bag.compare(bag.size() - 4, 4, ".bag") == 0 ? bag.substr(0, bag.size() - 4) : bag) +
        ".gyro_flow.yaml";
    if (std::ifstream(beside).good()) args->gyro_config_used = beside;
  } else if (args->gyro_config != "none") {
    if (!std::ifstream(args->gyro_config).good())
      return command_line.usageError("--gyro-config " + args->gyro_config + ": cannot read the file");
    args->gyro_config_used = args->gyro_config;
  }
  const std::string priors_problem = args->priors.validate();
  if (!priors_problem.empty()) return command_line.usageError(priors_problem);
  return std::nullopt;
}

// The priors the gyro config states (nothing without one). Throws naming the file and key.
void readPriors(Arguments& args) {
  if (args.gyro_config_used.empty()) return;
  const deep_ois::YamlParameters yaml(args.gyro_config_used);
  deep_ois::CalibrationPriors& priors = args.priors;
  priors.source = args.gyro_config_used;
  double readout_s = 0.0;
  if (yaml.get("readout_time", readout_s)) priors.readout_time_s = readout_s;
  std::vector<double> rotation;
  if (yaml.get("imu_to_camera_rotation", rotation) && !rotation.empty()) {
    if (rotation.size() != 9)
      throw std::invalid_argument(yaml.describe("imu_to_camera_rotation") + ": needs 9 numbers (row-major R_cam_imu)");
    Eigen::Matrix3d R;
    for (int i = 0; i < 9; ++i) R(i / 3, i % 3) = rotation[static_cast<std::size_t>(i)];
    priors.imu_to_camera_rotation = R;
  }
  // The bias the gyro flow would subtract with this file: none unless it says so (a phone
  // logger's gyro already has the phone's drift estimate removed).
  std::vector<double> bias;
  priors.gyro_bias_rad_s = Eigen::Vector3d::Zero();
  if (yaml.get("gyro_bias", bias) && !bias.empty()) {
    if (bias.size() != 3) throw std::invalid_argument(yaml.describe("gyro_bias") + ": needs 3 numbers (rad/s)");
    priors.gyro_bias_rad_s = Eigen::Vector3d(bias[0], bias[1], bias[2]);
  }
  const std::string problem = priors.validate();
  if (!problem.empty()) throw std::invalid_argument(args.gyro_config_used + ": " + problem);
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

std::string rotationFlag(const Eigen::Matrix3d& R) {
  std::ostringstream flag;
  flag << std::setprecision(9) << "--rotation ";
  for (int i = 0; i < 9; ++i) flag << (i ? "," : "") << (std::abs(R(i / 3, i % 3)) < 1e-12 ? 0.0 : R(i / 3, i % 3));
  return flag.str();
}

// Where a printed value came from.
std::string sourceText(deep_ois::CalibrationValueSource source, const std::string& flag, const Arguments& args) {
  switch (source) {
    case deep_ois::CalibrationValueSource::kData: return " (from the data)";
    case deep_ois::CalibrationValueSource::kPrior: return " (from " + args.gyro_config_used + ", held)";
    case deep_ois::CalibrationValueSource::kCaller: return " (held: " + flag + ")";
  }
  return "";
}

// What would let a refused calibration through: the flags that hold the values the gyro config
// states (or, without one, which values to find), and the motion to record when the data is too
// weak for what no file states.
void printRemedy(const Arguments& args, const deep_ois::CalibrationBag& bag,
                 const deep_ois::PriorCalibration& calibration) {
  const deep_ois::CalibrationResult& result = calibration.result;
  const deep_ois::CalibrationOptions& options = calibration.options;
  const deep_ois::CalibrationPriors& stated = args.priors;
  const std::string file = args.gyro_config_used.empty() ? "" : args.gyro_config_used;
  std::vector<std::string> flags, missing;
  std::ostringstream flag;
  flag << std::setprecision(9);
  if (result.refused.readout_time && options.estimate_readout_time) {
    if (stated.readout_time_s) {
      flag << "--readout " << *stated.readout_time_s;
      flags.push_back(flag.str());
    } else {
      missing.push_back("--readout SECONDS (the sensor's rolling-shutter readout; convert_recording writes a phone "
                        "logger's to OUT.gyro_flow.yaml, which calibrate reads with --gyro-config)");
    }
  }
  if (result.refused.rotation && options.estimate_rotation) {
    if (stated.imu_to_camera_rotation) {
      flags.push_back(rotationFlag(*stated.imu_to_camera_rotation));
    } else if (result.nearest_permutation_index >= 0 || result.coarse_permutation_index >= 0) {
      const int index = result.nearest_permutation_index >= 0 ? result.nearest_permutation_index
                                                              : result.coarse_permutation_index;
      missing.push_back(rotationFlag(deep_ois::signedAxisPermutations()[static_cast<std::size_t>(index)]) +
                        " (the axis permutation the recording's search picks, if the IMU is mounted along the "
                        "camera's axes)");
    } else {
      missing.push_back("--rotation r00,...,r22 (R_cam_imu, e.g. from CAD or a recording with more rotation)");
    }
  }
  if (result.refused.gyro_bias && options.estimate_gyro_bias && stated.gyro_bias_rad_s) {
    flags.push_back(stated.gyro_bias_rad_s->isZero() ? std::string("--no-bias")
                                                     : "--no-bias (and gyro_bias as " + file + " states)");
  }
  const bool applied_all = args.apply_priors && !file.empty();
  if (!flags.empty()) {
    std::string joined;
    for (const std::string& f : flags) joined += " " + f;
    std::fprintf(stderr, "  remedy: hold %s:\n    rosrun deep_ois calibrate --bag %s --out %s%s%s\n",
                 file.empty() ? "what you know" : ("what " + file + " states").c_str(), args.bag_path.c_str(),
                 args.out_path.c_str(), joined.c_str(),
                 applied_all ? "" : (file.empty() ? "" : "  (or drop --gyro-config none)"));
  }
  for (const std::string& m : missing)
    std::fprintf(stderr, "  remedy: %s %s\n", flags.empty() ? "hold" : "or hold", m.c_str());
  // What no file states (the time offset), or what is refused with every stated value held: the
  // recording is too weak, and only another recording helps.
  std::vector<std::string> motion;
  if (result.refused.motion) motion.push_back("turns about all three camera axes (none of this one's is enough)");
  if (result.refused.time_offset)
    motion.push_back("rates that change within fractions of a second, for the time offset (back-and-forth turns, "
                     "a few per second, about any axis)");
  if (result.refused.readout_time && !stated.readout_time_s)
    motion.push_back("vertical image motion, for the readout (tilt about the camera x axis, roll about the lens)");
  if (result.refused.rotation && !stated.imu_to_camera_rotation)
    motion.push_back("turns about all three camera axes, for the mount");
  if (result.refused.gyro_bias && !stated.gyro_bias_rad_s)
    motion.push_back("more seconds of turning, for the bias (or --no-bias when the gyro is already bias-corrected)");
  if (!motion.empty()) {
    // (After a flag to hold, recording again is the alternative.)
    const std::vector<double>& stamps = bag.data.frame_stamps_s;
    const double seconds = stamps.size() > 1 ? stamps.back() - stamps.front() : 0.0;
    std::string joined;
    for (std::size_t i = 0; i < motion.size(); ++i) joined += (i ? "; " : "") + motion[i];
    std::fprintf(stderr,
                 "  remedy: %srecord again (this recording: %.1f s of frames, gyro RMS %.3f %.3f %.3f rad/s about its "
                 "principal axes): 10 s or more of brisk turns, about 0.4 rad/s each, facing a scene 4 m away or "
                 "more, with %s (docs/calibration.md, the calibration protocol)\n",
                 flags.empty() && missing.empty() ? "" : "or ", seconds, result.rate_rms_rad_s(0),
                 result.rate_rms_rad_s(1), result.rate_rms_rad_s(2), joined.c_str());
  }
}

// Only the refusal and the figures that led to it: a refused estimate's values (placeholders when
// the refinement never ran) are not results.
void printRefusal(const Arguments& args, const deep_ois::CalibrationBag& bag,
                  const deep_ois::PriorCalibration& calibration) {
  const deep_ois::CalibrationResult& result = calibration.result;
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
  for (const std::string& decision : calibration.decisions) std::fprintf(stderr, "  prior: %s\n", decision.c_str());
  printRemedy(args, bag, calibration);
}

// The estimate, its 1-sigma, where each value came from and how it was reached.
void printCalibration(const Arguments& args, const deep_ois::CalibrationBag& bag,
                      const deep_ois::PriorCalibration& calibration, double reading_s) {
  const deep_ois::CalibrationResult& result = calibration.result;
  const deep_ois::CalibrationOptions& options = args.options;
  const deep_ois::CameraImuCalibration& c = result.calibration;
  std::printf(
      "calibrate: %s: %zu frames, %d of %zu pairs used, %d tracks; lens shift handling %s\n",
      args.bag_path.c_str(), bag.frames, result.pairs_used, bag.data.pairs.size(), result.tracks_used,
      deep_ois::toString(options.lens_shift));
  if (!args.gyro_config_used.empty() && args.apply_priors) {
    std::printf("  priors from %s:%s%s%s (each held only when the data cannot determine it)\n",
                args.gyro_config_used.c_str(), args.priors.readout_time_s ? " readout" : "",
                args.priors.imu_to_camera_rotation ? " mount" : "", args.priors.gyro_bias_rad_s ? " gyro bias" : "");
  }
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
  // every recording shares, plus what the held values' own 1-sigma moves it by); the statistical
  // part in brackets is what the refusals judge.
  std::printf("  time offset     %+9.3f ms  +- %.3f ms (statistical %.3f)%s\n", c.time_offset_s * 1e3,
              c.time_offset_sigma_s * 1e3, result.statistical.time_offset_s * 1e3,
              sourceText(calibration.time_offset, "--time-offset", args).c_str());
  std::printf("  readout time    %9.3f ms  +- %.3f ms (statistical %.3f)%s\n", c.readout_time_s * 1e3,
              c.readout_time_sigma_s * 1e3, result.statistical.readout_time_s * 1e3,
              sourceText(calibration.readout_time, "--readout", args).c_str());
  std::printf("  gyro bias       [%+.5f %+.5f %+.5f] rad/s  +- %.5f%s\n", c.gyro_bias_rad_s(0),
              c.gyro_bias_rad_s(1), c.gyro_bias_rad_s(2), c.gyro_bias_sigma_rad_s.maxCoeff(),
              sourceText(calibration.gyro_bias, "--no-bias", args).c_str());
  std::printf("  R_cam_imu       +- (%.3f %.3f %.3f) deg about camera x y z (statistical %.3f %.3f %.3f)%s\n",
              c.rotation_sigma_rad(0) * kRadToDeg, c.rotation_sigma_rad(1) * kRadToDeg,
              c.rotation_sigma_rad(2) * kRadToDeg, result.statistical.rotation_rad(0) * kRadToDeg,
              result.statistical.rotation_rad(1) * kRadToDeg, result.statistical.rotation_rad(2) * kRadToDeg,
              sourceText(calibration.rotation, "--rotation", args).c_str());
  // A readout this close to 0 is usually a global shutter, whose readout is known: estimated
  // from a recording with little motion, the offset and readout can slide together along
  // their ridge by a millisecond at a 1-sigma of 0.2-0.3 ms (docs/calibration_uncertainty.md).
  for (const std::string& note : result.notes) std::printf("  note: %s\n", note.c_str());
  for (const std::string& decision : calibration.decisions) std::printf("  prior: %s\n", decision.c_str());
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
  std::printf("  time: %.2f s reading and tracking (%.2f s KLT), %.2f s estimating (%d calibrations)\n", reading_s,
              bag.tracking_seconds, calibration.seconds, calibration.calibrations);
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
                      const deep_ois::PriorCalibration& calibration, const std::string& lens_yaml) {
  const deep_ois::CalibrationResult& result = calibration.result;
  deep_ois::CalibrationProvenance provenance;
  // Which value came from where, by parameter name.
  std::string from_data, from_file, held;
  auto add = [&](deep_ois::CalibrationValueSource source, const char* name) {
    std::string& list = source == deep_ois::CalibrationValueSource::kData    ? from_data
                        : source == deep_ois::CalibrationValueSource::kPrior ? from_file
                                                                              : held;
    list += (list.empty() ? "" : ", ") + std::string(name);
  };
  add(calibration.time_offset, "time_offset");
  add(calibration.readout_time, "readout_time");
  add(calibration.gyro_bias, "gyro_bias");
  add(calibration.rotation, "imu_to_camera_rotation");
  if (!from_data.empty()) provenance.notes.push_back("from the data: " + from_data);
  if (!from_file.empty())
    provenance.notes.push_back("from " + args.gyro_config_used + " (the recording cannot determine them): " + from_file);
  if (!held.empty()) provenance.notes.push_back("held by the command line: " + held);
  for (const std::string& decision : calibration.decisions) provenance.notes.push_back(decision);
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
    try {
      readPriors(args);
    } catch (const std::exception& e) {
      // With --gyro-config none the file beside the bag only names values in a remedy.
      if (args.apply_priors) throw;
      args.priors = deep_ois::CalibrationPriors();
    }
    double reading_s = 0.0;
    const deep_ois::CalibrationBag bag = readBag(args, &reading_s);
    if (args.rotation_text == "tf") {
      if (!bag.tf_imu_to_camera_rotation) {
        std::fprintf(stderr, "calibrate: --rotation tf, but %s: %s\n", args.bag_path.c_str(), bag.tf_problem.c_str());
        return 1;
      }
      args.options.imu_to_camera_rotation = *bag.tf_imu_to_camera_rotation;
    }
    const deep_ois::PriorCalibration calibration = deep_ois::calibrateWithPriors(
        bag.data, args.options, args.apply_priors ? args.priors : deep_ois::CalibrationPriors());
    const deep_ois::CalibrationResult& result = calibration.result;
    if (!result.ok()) {
      printRefusal(args, bag, calibration);
      return 1;
    }
    printCalibration(args, bag, calibration, reading_s);
    std::string lens_yaml;
    if (args.lens_shift) {
      const std::optional<std::string> lens = calibrateLensLog(args, bag, result.calibration);
      if (!lens) return 1;
      lens_yaml = *lens;
    }
    writeCalibration(args, bag, calibration, lens_yaml);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate: %s\n", e.what());
    return 1;
  }
}
