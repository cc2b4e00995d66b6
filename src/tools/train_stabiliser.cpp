// Per-camera training in one command: recordings of an OIS camera (rosbags) in, a learned
// stabiliser model (core/ois/stabiliser_model.h) and a report out.
//   1. Ground truth per recording: the gyro-anchored lens motion from the images (or the
//      simulator's truth with --target truth), cached beside the model so a re-run resumes.
//   2. The fit (core/ois/stabiliser_fit.h), with progress.
//   3. Held-out recordings scored: lens-motion residual without and with the model.
//   4. A calibration check: the images' track residual with the gyro's rotations tells whether
//      the camera-IMU calibration (time offset, readout, rotation) fits the recordings.
// The scores in the paper's metric come from `evaluate --stabiliser MODEL.yaml` on the held-out
// bags; scripts/train_camera.sh runs both.
#include <ros/package.h>

#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/ros/bag/stabiliser_training_data.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/dataset_hash.h"
#include "deep_ois/tools/support/line_plot.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

namespace fs = std::filesystem;
constexpr int kCacheVersion = 1;
// A median track residual above this (pixels) after the lens is fitted means the gyro's rotations
// do not explain the images: a wrong time offset, readout or IMU -> camera rotation (with the
// right calibration the simulator's recordings give 0.1-0.2 px, the KLT noise).
constexpr double kCalibrationSuspectPx = 0.5;

// The cache of one recording's data: a text file beside the model (resume after an interruption
// without recomputing the ground truth of finished recordings).
// Keyed by the bag's absolute path (recordings of several cameras often share file names).
std::string cachePath(const std::string& cache_dir, const std::string& bag, const std::string& target) {
  std::string key = fs::absolute(bag).lexically_normal().string();
  for (char& c : key) {
    if (c == '/') c = '_';
  }
  return cache_dir + "/" + key + "." + target + ".txt";
}

void writeCache(const std::string& path, const std::string& bag,
                const deep_ois::StabiliserRecordingData& data) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial);
    out.precision(17);
    out << "deep_ois_stabiliser_cache " << kCacheVersion << "\n" << "bag " << bag << "\n";
    out << "size " << fs::file_size(bag) << "\n";
    const auto& c = data.camera;
    out << "camera " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx
        << " " << c.cy << " " << c.readout_time_s << " " << c.frame_rate_hz << "\n";
    out << "counts " << data.frame_pairs << " " << data.pairs_without_gyro << " "
        << data.pairs_without_tracks << " " << data.median_track_residual_px << "\n";
    out << "focal " << data.recording.focal_px << "\n";
    for (const auto& r : data.recording.rates)
      out << "r " << r.stamp_s << " " << r.rate_rad_s.x() << " " << r.rate_rad_s.y() << " "
          << r.rate_rad_s.z() << "\n";
    for (const auto& o : data.recording.observations)
      out << "o " << o.t_a_s << " " << o.t_b_s << " " << o.motion_px.x() << " " << o.motion_px.y()
          << " " << o.weight << "\n";
    out << "end\n";
    if (!out) throw std::runtime_error(partial + ": write failed");
  }
  fs::rename(partial, path);  // complete files only
}

// The cached data when it exists, is complete and belongs to this bag (same size).
std::optional<deep_ois::StabiliserRecordingData> readCache(const std::string& path,
                                                           const std::string& bag) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  deep_ois::StabiliserRecordingData data;
  data.recording.name = bag;
  std::string word, line;
  int version = 0;
  if (!(in >> word >> version) || word != "deep_ois_stabiliser_cache" || version != kCacheVersion)
    return std::nullopt;
  bool complete = false;
  while (in >> word) {
    if (word == "bag") {
      std::getline(in, line);
    } else if (word == "size") {
      std::uintmax_t size = 0;
      in >> size;
      if (size != fs::file_size(bag)) return std::nullopt;
    } else if (word == "camera") {
      auto& c = data.camera;
      in >> c.width >> c.height >> c.fx >> c.fy >> c.cx >> c.cy >> c.readout_time_s >> c.frame_rate_hz;
    } else if (word == "counts") {
      in >> data.frame_pairs >> data.pairs_without_gyro >> data.pairs_without_tracks >>
          data.median_track_residual_px;
    } else if (word == "focal") {
      in >> data.recording.focal_px;
    } else if (word == "r") {
      deep_ois::CameraRateSample r;
      in >> r.stamp_s >> r.rate_rad_s.x() >> r.rate_rad_s.y() >> r.rate_rad_s.z();
      data.recording.rates.push_back(r);
    } else if (word == "o") {
      deep_ois::LensMotionObservation o;
      in >> o.t_a_s >> o.t_b_s >> o.motion_px.x() >> o.motion_px.y() >> o.weight;
      data.recording.observations.push_back(o);
    } else if (word == "end") {
      complete = true;
      break;
    } else {
      return std::nullopt;
    }
    if (!in) return std::nullopt;
  }
  if (!complete) return std::nullopt;
  return data;
}

// RMS of |predicted - observed| lens motion over a recording's usable observations, and with no
// model (predicted 0); pixels.
struct HeldOutScore {
  double rms_px = 0.0, rms_without_px = 0.0;
  std::size_t observations = 0;
};
HeldOutScore scoreHeldOut(const deep_ois::StabiliserParameters& parameters,
                          const std::vector<deep_ois::StabiliserFitRecording>& recordings,
                          const deep_ois::StabiliserFitOptions& options) {
  const deep_ois::LensMotionScore score = deep_ois::scoreLensMotion(parameters, recordings, options);
  return {score.rms_px, score.rms_without_model_px, score.observations};
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "train_stabiliser",
      "Learns a camera's optical image stabiliser from its recordings (rosbags with images, IMU, "
      "camera_info and the IMU -> camera transform): the lens motion per frame pair and row patch "
      "from the images with the gyro's rotations (gyro-anchored ground truth), then the "
      "stabiliser model fitted to it. Writes MODEL.yaml (parameters, camera, training data) and "
      "MODEL_fit.png (the fit's loss curve), and "
      "keeps each recording's ground truth in a cache directory (a re-run resumes from it).",
      "Exit status: 0 done, 1 no usable recording or the fit failed, 2 usage, 3 done but some "
      "recordings could not be read or the calibration looks wrong.");
  CLI::App& app = command_line.app();
  std::vector<std::string> bags, held_out_bags;
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  std::string out_path, name, target = "images";
  app.add_option("--bags", bags, "training recordings")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--held-out", held_out_bags, "recordings scored, not trained on")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--gyro-config", gyro_config, "gyro flow parameters of the camera (YAML)")
      ->capture_default_str()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--out", out_path, "the model to write")->required()->type_name("MODEL.yaml");
  app.add_option("--name", name, "what the model is for (default: the camera's summary)");
  std::string cache_dir;
  app.add_option("--cache", cache_dir,
                 "where each recording's ground truth is kept (default MODEL.yaml.cache); a "
                 "recording found there is not recomputed, so runs for several models can share it")
      ->type_name("DIR");
  app.add_option("--target", target,
                 "lens motion from the 'images' (gyro-anchored ground truth), the camera's own "
                 "lens-shift 'log' (with the gyro config's lens_shift_* convention) or the "
                 "simulator's 'truth'")
      ->check(deep_ois::oneOf({"images", "log", "truth"}))
      ->capture_default_str();
  deep_ois::StabiliserFitOptions fit_options;
  command_line.addNumber("--iterations", fit_options.iterations,
                         "Levenberg-Marquardt iterations per candidate")
      ->check(deep_ois::atLeast(1));
  command_line.addNumber("--warm-up", fit_options.warm_up_s,
                         "seconds of each recording's gyro before its first scored pair")
      ->check(deep_ois::atLeast(0));
  bool no_progress = false;
  app.add_flag("--no-progress", no_progress, "no progress bars");
  std::string forced_candidate;
  app.add_option("--candidate", forced_candidate,
                 "keep the candidate whose name contains this (e.g. excursion_v1) instead of the "
                 "best on the held-out recordings, for comparisons");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (gyro_config.empty())
    return command_line.usageError("--gyro-config: package deep_ois not found, so give the file");

  const auto started = std::chrono::steady_clock::now();
  deep_ois::GyroFlowParameters gyro;
  try {
    gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s: %s\n", gyro_config.c_str(), e.what());
    return 2;
  }
  const deep_ois::LensMotionTarget lens_target =
      target == "truth" ? deep_ois::LensMotionTarget::kSimulatorTruth
      : target == "log" ? deep_ois::LensMotionTarget::kLensLog
                        : deep_ois::LensMotionTarget::kImages;
  if (cache_dir.empty()) cache_dir = out_path + ".cache";
  std::error_code ignored;
  fs::create_directories(cache_dir, ignored);

  // ---- 1. Ground truth per recording (cached). ----
  int failures = 0;
  bool calibration_suspect = false;
  std::vector<deep_ois::CameraDescription> cameras;
  auto readAll = [&](const std::vector<std::string>& paths, const char* what) {
    std::vector<deep_ois::StabiliserFitRecording> recordings;
    std::unique_ptr<deep_ois::ProgressBar> progress;
    if (!no_progress) progress = std::make_unique<deep_ois::ProgressBar>(paths.size(), what);
    std::size_t done = 0;
    for (const std::string& bag : paths) {
      const std::string cache = cachePath(cache_dir, bag, target);
      try {
        std::optional<deep_ois::StabiliserRecordingData> data = readCache(cache, bag);
        const bool cached = data.has_value();
        if (!data) {
          data = deep_ois::readStabiliserRecording(bag, gyro, lens_target);
          writeCache(cache, bag, *data);
        }
        if (progress) progress->update(++done);
        std::fprintf(stderr,
                     "\ntrain_stabiliser: %s: %zu pairs, %zu lens motions%s%s%s, track residual "
                     "%.3f px%s\n",
                     bag.c_str(), data->frame_pairs, data->recording.observations.size(),
                     data->pairs_without_gyro
                         ? (", " + std::to_string(data->pairs_without_gyro) + " pairs without gyro").c_str()
                         : "",
                     data->pairs_without_tracks
                         ? (", " + std::to_string(data->pairs_without_tracks) +
                            " pairs with too few tracks (left out)").c_str()
                         : "",
                     data->pairs_without_log
                         ? (", " + std::to_string(data->pairs_without_log) +
                            " pairs the lens log does not cover (left out)").c_str()
                         : "",
                     data->median_track_residual_px, cached ? " (cached)" : "");
        if (lens_target == deep_ois::LensMotionTarget::kImages &&
            data->median_track_residual_px > kCalibrationSuspectPx) {
          calibration_suspect = true;
          std::fprintf(stderr,
                       "train_stabiliser: WARNING: %s: the gyro's rotations leave %.2f px median "
                       "track residual (> %.1f px with the lens fitted): the camera-IMU calibration "
                       "(time_offset, readout_time, IMU -> camera rotation) does not fit this "
                       "recording; run calibrate on it\n",
                       bag.c_str(), data->median_track_residual_px, kCalibrationSuspectPx);
        }
        cameras.push_back(data->camera);
        recordings.push_back(std::move(data->recording));
      } catch (const std::exception& e) {
        // One unreadable recording must not lose the others.
        if (progress) progress->update(++done);
        std::fprintf(stderr, "\ntrain_stabiliser: %s (skipped)\n", e.what());
        ++failures;
      }
    }
    return recordings;
  };
  const std::vector<deep_ois::StabiliserFitRecording> training = readAll(bags, "recordings");
  const std::vector<deep_ois::StabiliserFitRecording> held_out =
      readAll(held_out_bags, "held-out recordings");
  if (training.empty()) {
    std::fprintf(stderr, "train_stabiliser: no training recording could be read\n");
    return 1;
  }
  // One camera, or a generic model across cameras (its file then names no camera, and the
  // nodelet has nothing to compare: the parameters are in focal-length units).
  bool one_camera = true;
  for (const auto& camera : cameras) {
    const std::string difference = cameras.front().differencesTo(camera);
    if (!difference.empty()) {
      std::fprintf(stderr,
                   "train_stabiliser: the recordings are of more than one camera (%s: %s vs %s): "
                   "training a generic model, which records no camera\n",
                   difference.c_str(), cameras.front().summary().c_str(), camera.summary().c_str());
      one_camera = false;
      break;
    }
  }

  // ---- 2. The fit. ----
  deep_ois::StabiliserFitResult fit;
  try {
    std::unique_ptr<deep_ois::ProgressBar> progress;
    if (!no_progress) progress = std::make_unique<deep_ois::ProgressBar>(0, "fit steps");
    fit = deep_ois::fitStabiliser(training, fit_options, [&](std::size_t done, std::size_t total) {
      if (!progress) return;
      if (done == 1) progress = std::make_unique<deep_ois::ProgressBar>(total, "fit steps");
      progress->update(done);
    });
    if (progress) std::fprintf(stderr, "\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  }
  for (const std::string& line : fit.log) std::fprintf(stderr, "train_stabiliser: %s\n", line.c_str());
  // Learned dynamics on top of the physical chain, scored on the held-out recordings; the best is
  // kept (core/ois/stabiliser_candidates.h).
  const deep_ois::StabiliserSelection selection =
      deep_ois::selectStabiliser(fit, training, held_out, fit_options);
  std::size_t kept = selection.kept;
  if (!forced_candidate.empty()) {
    kept = selection.candidates.size();
    for (std::size_t k = 0; k < selection.candidates.size() && kept == selection.candidates.size(); ++k)
      if (selection.candidates[k].name.find(forced_candidate) != std::string::npos) kept = k;
    if (kept == selection.candidates.size()) {
      std::fprintf(stderr, "train_stabiliser: --candidate: no candidate named '%s'\n", forced_candidate.c_str());
      return 2;
    }
  }
  fit.parameters = selection.candidates[kept].parameters;
  fit.rms_px = selection.candidates[kept].training.rms_px;
  // The model kept must beat "no lens motion" on data it was not fitted to: an OIS-off camera
  // trains to it (without --held-out, the check refits the physical chain on 3/4 of each recording).
  const deep_ois::NoLensMotionCheck lens_check =
      deep_ois::checkFitAgainstNoLensMotion(fit.parameters, training, held_out, fit_options);
  std::fprintf(stderr, "train_stabiliser: check against no lens motion %s\n", lens_check.reason.c_str());
  if (lens_check.refused) {
    std::fprintf(stderr,
                 "train_stabiliser: the fit is REFUSED (it does not predict the lens motion better than "
                 "no lens motion): writing 'no lens motion' (the compensation is then the plain gyro: a "
                 "camera without OIS or with OIS off)\n");
    fit.parameters = deep_ois::noLensMotionParameters();
    fit.rms_px = fit.rms_physical_px = fit.rms_without_model_px;
  }

  // ---- 3. Held-out scores and the model file. ----
  deep_ois::StabiliserModelFile model;
  model.parameters = fit.parameters;
  if (one_camera) model.camera = cameras.front();
  model.name = name.empty() ? (one_camera ? model.camera.summary() : "generic") : name;
  model.training.target = lens_target == deep_ois::LensMotionTarget::kImages
                              ? "gyro-anchored lens shift (images)"
                          : lens_target == deep_ois::LensMotionTarget::kLensLog
                              ? "the camera's lens-shift log"
                              : "simulator truth";
  model.training.data_files = bags;
  model.training.recordings = training.size();
  model.training.observations = fit.observations_used;
  model.training.rms_without_model_px = fit.rms_without_model_px;
  model.training.rms_px = fit.rms_px;
  const HeldOutScore score = scoreHeldOut(fit.parameters, held_out, fit_options);
  model.training.held_out_rms_without_model_px = score.rms_without_px;
  model.training.held_out_rms_px = score.rms_px;
  try {
    model.training.data_sha256 = deep_ois::sha256OfFiles(bags);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: data hash: %s\n", e.what());
  }
  model.training.training_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  try {
    model.save(out_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  }

  // The fit's loss curve beside the model.
  std::string plot_path = out_path;
  if (plot_path.size() > 5 && plot_path.substr(plot_path.size() - 5) == ".yaml")
    plot_path.resize(plot_path.size() - 5);
  plot_path += "_fit.png";
  {
    const cv::Mat plot = deep_ois::drawLinePlot(
        {{"training lens motions", fit.rms_history, cv::Scalar(200, 80, 0)}},
        "train_stabiliser: fit of " + fs::path(out_path).filename().string(),
        "Levenberg-Marquardt step", "RMS lens-motion residual [px]", true);
    if (!cv::imwrite(plot_path, plot))
      std::fprintf(stderr, "train_stabiliser: cannot write %s\n", plot_path.c_str());
  }
  const auto& p = fit.parameters;
  std::printf("Stabiliser model %s (%s); fit curve %s\n\n", out_path.c_str(), model.name.c_str(),
              plot_path.c_str());
  std::printf("| parameter | value |\n|---|---|\n");
  std::printf("| gain | [%.3f %.3f; %.3f %.3f] |\n", p.gain(0, 0), p.gain(0, 1), p.gain(1, 0),
              p.gain(1, 1));
  std::printf("| centring corner | %.3f Hz |\n| actuator | %.1f Hz, damping %.2f |\n",
              p.highpass_corner_hz, p.actuator_natural_hz, p.actuator_damping);
  std::printf("| sensor lag | %.2f ms |\n| stroke | %.3f x %.3f deg (%s) |\n",
              1000.0 * p.sensor_lag_s, p.stroke_x_deg, p.stroke_y_deg,
              p.circular_stroke ? "ellipse" : "box");
  std::printf("| pan detection | %s |\n",
              p.pan_detection_rate_rad_s > 0.0
                  ? (std::to_string(p.pan_detection_rate_rad_s) + " rad/s, release " +
                     std::to_string(p.pan_release_corner_hz) + " Hz").c_str()
                  : "off");
  std::printf("| residual bank | %zu time constants |\n", p.residual_time_constants_s.size());
  std::printf("| nonlinear residual | %s |\n\n", p.nonlinear_features.empty() ? "none" : p.nonlinear_features.c_str());
  std::printf("Candidates, lens-motion RMS residual (pixels):\n\n| candidate | training | held out |\n|---|---:|---:|\n");
  for (const auto& candidate : selection.candidates)
    std::printf("| %s | %.4f | %.4f |\n", candidate.name.c_str(), candidate.training.rms_px,
                candidate.held_out.rms_px);
  std::printf("\n%s\n\n", kept == selection.kept
                                ? selection.reason.c_str()
                                : ("kept '" + selection.candidates[kept].name +
                                   "' as --candidate asked (" + selection.reason + ")").c_str());
  std::printf("Lens motion per frame pair and row patch, RMS residual (pixels):\n\n");
  std::printf("| data | lens motions | without a lens model | physical model | with residual |\n");
  std::printf("|---|---:|---:|---:|---:|\n");
  std::printf("| training (%zu recordings) | %zu | %.3f | %.3f | %.3f |\n", training.size(),
              fit.observations_used, fit.rms_without_model_px, fit.rms_physical_px, fit.rms_px);
  if (!held_out.empty()) {
    std::printf("| held out (%zu recordings) | %zu | %.3f | | %.3f |\n", held_out.size(),
                score.observations, score.rms_without_px, score.rms_px);
  }
  if (lens_check.refused) {
    std::printf("\nThe fit was refused for 'no lens motion' (%s).\n", lens_check.reason.c_str());
  }
  std::printf("\ntrained in %.1f s (ground truth included; cached recordings are not recomputed)\n",
              model.training.training_time_s);
  if (calibration_suspect) {
    std::printf("\nWARNING: the calibration does not fit some recordings (see above): the model is "
                "only as good as the gyro's rotations; run calibrate and train again.\n");
  }
  return failures > 0 || calibration_suspect ? 3 : 0;
}
