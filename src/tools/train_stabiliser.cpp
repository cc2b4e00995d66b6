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

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
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
#include "deep_ois/tools/support/csv_plot.h"
#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/tools/support/stabiliser_training_cache.h"
#include "deep_ois/tools/support/stabiliser_training_report.h"

namespace {

namespace fs = std::filesystem;
// A median track residual above this (pixels) after the lens is fitted means the gyro's rotations
// do not explain the images: a wrong time offset, readout or IMU -> camera rotation (with the
// right calibration the simulator's recordings give 0.1-0.2 px, the KLT noise).
constexpr double kCalibrationSuspectPx = 0.5;

}  // namespace

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "train_stabiliser",
      "Learns a camera's optical image stabiliser from its recordings (rosbags with images, IMU, "
      "camera_info and the IMU -> camera transform): the lens motion per frame pair and row patch "
      "from the images with the gyro's rotations (gyro-anchored ground truth), then the "
      "stabiliser model fitted to it. Writes MODEL.yaml (parameters, camera, training data) and "
      "MODEL_fit.csv and MODEL_fit.png (the fit's loss curve), and "
      "keeps each recording's ground truth in a cache directory (a re-run resumes from it).",
      "Exit status: 0 done, 1 no usable recording or the fit failed, 2 usage, 3 done but some "
      "recordings could not be read, the calibration looks wrong or the fitted parameters are "
      "implausible.");
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

  try {  // now, not after the fit: a mistyped --out folder must not cost the fit
    deep_ois::StabiliserModelFile::checkSavable(out_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: --out: %s\n", e.what());
    return 2;
  }

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
      const std::string cache = deep_ois::stabiliserCachePath(cache_dir, bag, target);
      // A line of its own after a bar drawn on a terminal.
      const char* newline = progress && progress->drawing() ? "\n" : "";
      try {
        const deep_ois::StabiliserCacheKey key = deep_ois::stabiliserCacheKey(bag, gyro, target);
        std::string stale;
        std::optional<deep_ois::StabiliserRecordingData> data =
            deep_ois::readStabiliserCache(cache, key, bag, &stale);
        const bool cached = data.has_value();
        if (!data) {
          if (stale != "no cache") {
            std::fprintf(stderr, "%strain_stabiliser: %s: cached data not used: %s\n", newline,
                         bag.c_str(), stale.c_str());
          }
          data = deep_ois::readStabiliserRecording(bag, gyro, lens_target);
          deep_ois::writeStabiliserCache(cache, key, bag, *data);
        }
        if (progress) progress->update(++done);
        std::fprintf(stderr, "%strain_stabiliser: %s\n", newline,
                     deep_ois::recordingSummary(bag, *data, lens_target, cached).c_str());
        const std::string readout =
            deep_ois::readoutMismatch(*data, gyro.rolling_shutter.readout_time_s);
        if (!readout.empty()) {
          calibration_suspect = true;
          std::fprintf(stderr, "train_stabiliser: WARNING: %s: %s\n", bag.c_str(), readout.c_str());
        }
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
        std::fprintf(stderr, "%strain_stabiliser: %s (skipped)\n", newline, e.what());
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
  fit_options.readout_time_s = gyro.rolling_shutter.readout_time_s;  // for its timing check
  deep_ois::StabiliserFitResult fit;
  try {
    std::unique_ptr<deep_ois::ProgressBar> progress;
    if (!no_progress) progress = std::make_unique<deep_ois::ProgressBar>(0, "fit steps");
    fit = deep_ois::fitStabiliser(training, fit_options, [&](std::size_t done, std::size_t total) {
      if (!progress) return;
      progress->setTotal(total);  // known once the fit runs; the rate counts from the start
      progress->update(done);
    });
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  }
  for (const std::string& line : fit.log) std::fprintf(stderr, "train_stabiliser: %s\n", line.c_str());
  // How the fit ended: parameters on a bound of the fit, values no module has (with the cause).
  for (const std::string& line : fit.review.on_bound)
    std::fprintf(stderr, "train_stabiliser: note: %s\n", line.c_str());
  for (const std::string& line : fit.review.implausible)
    std::fprintf(stderr, "train_stabiliser: WARNING: implausible %s\n", line.c_str());
  // The lens absorbs timing errors (the track residual stays small): the fit's timing check.
  for (const std::string& line : fit.review.timing)
    std::fprintf(stderr, "train_stabiliser: WARNING: %s\n", line.c_str());
  if (!fit.review.timing.empty()) calibration_suspect = true;
  bool implausible = !fit.review.implausible.empty();
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
    fit.parameters = deep_ois::noLensMotion();
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
  const deep_ois::StabiliserScore score =
      deep_ois::scoreStabiliser(fit.parameters, held_out, fit_options);
  // The physical model alone (without its residual bank and learned residual), as in the training
  // row.
  const deep_ois::StabiliserScore physical_score =
      deep_ois::scoreStabiliser(fit.parameters.physicalChain(), held_out, fit_options);
  // The refused fit's implausible values do not describe the model written (no lens motion).
  if (lens_check.refused) implausible = false;
  model.training.held_out_rms_without_model_px = score.rms_without_model_px;
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
    std::vector<double> steps(fit.rms_history.size());
    std::iota(steps.begin(), steps.end(), 1.0);
    deep_ois::CsvPlot plot;
    plot.title = "train_stabiliser: fit of " + fs::path(out_path).filename().string();
    plot.x_column = "step";
    plot.x_label = "accepted Levenberg-Marquardt step (all stages of the fit)";
    plot.y_labels = {"RMS lens-motion residual [px]"};
    plot.curves = {{"rms_px", "training lens motions"}};
    plot.log_y = true;
    const std::string csv_path = plot_path.substr(0, plot_path.size() - 4) + ".csv";
    const deep_ois::PlotOutcome outcome =
        deep_ois::writeAndPlotCsv(plot, {{"step", steps}, {"rms_px", fit.rms_history}}, csv_path, plot_path);
    if (!outcome.written)
      std::fprintf(stderr, "train_stabiliser: %s\n", deep_ois::describePlot(outcome, csv_path, plot_path).c_str());
  }
  const auto& p = fit.parameters;
  std::printf("Stabiliser model %s (%s); fit curve %s\n\n", out_path.c_str(), model.name.c_str(),
              plot_path.c_str());
  std::printf("%s\n", deep_ois::stabiliserParameterTable(p, fit.review).c_str());
  std::printf("Nonlinear residual (learned on the chain's state): %s\n\n",
              p.nonlinear_features.empty() ? "none" : p.nonlinear_features.c_str());
  std::printf("Candidates, lens-motion RMS residual (pixels):\n\n| candidate | training | held out |\n|---|---:|---:|\n");
  for (const auto& candidate : selection.candidates)
    std::printf("| %s | %.4f | %.4f |\n", candidate.name.c_str(), candidate.training.rms_px,
                candidate.held_out.rms_px);
  std::printf("\n%s\n\n", kept == selection.kept
                                ? selection.reason.c_str()
                                : ("kept '" + selection.candidates[kept].name +
                                   "' as --candidate asked (" + selection.reason + ")").c_str());
  std::printf("Lens motion per frame pair and row patch, RMS residual (pixels):\n\n");
  std::vector<deep_ois::LensMotionScoreRow> rows = {
      {"training", training.size(), fit.observations_used, fit.rms_without_model_px,
       fit.rms_physical_px, fit.rms_px}};
  if (!held_out.empty()) {
    rows.push_back({"held out", held_out.size(), score.observations, score.rms_without_model_px,
                    physical_score.rms_px, score.rms_px});
  }
  std::printf("%s", deep_ois::lensMotionTable(rows).c_str());
  if (lens_check.refused) {
    std::printf(
        "\nREFUSED: the fitted stabiliser is not the model written: %s. The model written is no "
        "lens motion (gain 0): the plain gyro.\n",
        lens_check.reason.c_str());
  }
  std::printf("\ntrained in %.1f s (ground truth included; cached recordings are not recomputed)\n",
              model.training.training_time_s);
  if (calibration_suspect) {
    std::printf("\nWARNING: the calibration does not fit some recordings (see above): the model is "
                "only as good as the gyro's rotations; run calibrate and train again.\n");
    for (const std::string& line : fit.review.timing) std::printf("- %s\n", line.c_str());
  }
  if (!fit.review.on_bound.empty()) {
    std::printf("\nParameters on a bound of the fit (the data wanted them further):\n");
    for (const std::string& line : fit.review.on_bound) std::printf("- %s\n", line.c_str());
  }
  if (implausible) {
    std::printf("\nWARNING: implausible parameters, the model is likely wrong:\n");
    for (const std::string& line : fit.review.implausible) std::printf("- %s\n", line.c_str());
  }
  return failures > 0 || calibration_suspect || implausible ? 3 : 0;
}
