// Per-camera training in one command: recordings of an OIS camera (rosbags) in, a learned
// stabiliser model (core/ois/stabiliser_model.h) and a report out. main runs four steps:
//   1. Ground truth per recording: the gyro-anchored lens motion from the images (or the camera's
//      lens log with --target log, the simulator's truth with --target truth), cached beside the
//      model so a re-run resumes; the images' track residual and a recorded readout tell whether
//      the camera-IMU calibration fits the recordings.
//   2. The fit (core/ois/stabiliser_fit.h), with progress; with --target log --fit-time-offset the
//      lens log is moved onto the gyro's clock first, as lens_log_fit does
//      (core/ois/lens_log_time_fit.h). Then the final rule (tools/support/stabiliser_training_choice.h):
//      the best candidate, checked against no lens motion on data it was not fitted to.
//   3. Held-out recordings scored, the model file and its plot written.
//   4. The report: the model written and why, the candidates, the residuals, and the warnings
//      that apply to the model written and the target in use.
// The scores in the paper's metric come from `evaluate --stabiliser MODEL.yaml` on the held-out
// bags; scripts/train_camera.sh runs both.
#include <ros/package.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_log_time_fit.h"
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
#include "deep_ois/tools/support/stabiliser_training_choice.h"
#include "deep_ois/tools/support/stabiliser_training_report.h"

namespace {

namespace fs = std::filesystem;
// A median track residual above this (pixels) after the lens is fitted means the gyro's rotations
// do not explain the images: a wrong time offset, readout or IMU -> camera rotation (with the
// right calibration the simulator's recordings give 0.1-0.2 px, the KLT noise).
constexpr double kCalibrationSuspectPx = 0.5;

struct Arguments {
  std::vector<std::string> bags, held_out_bags;
  std::string gyro_config, out_path, name, cache_dir, target = "images", forced_candidate;
  deep_ois::StabiliserFitOptions fit_options;
  deep_ois::StabiliserCandidateKinds kinds;  // with the network loaded
  bool no_progress = false;
  bool fit_time_offset = false;
  deep_ois::LensMotionTarget lens_target = deep_ois::LensMotionTarget::kImages;
};

// The recordings read (training or held out) and what reading them found.
struct RecordingSet {
  std::vector<deep_ois::StabiliserFitRecording> recordings;
  std::vector<deep_ois::CameraDescription> cameras;
  int failures = 0;                  // recordings that could not be read
  bool calibration_suspect = false;  // a readout or track residual that says the calibration is off
};

// The fit, and where the lens log was moved to fit it (--fit-time-offset).
struct FitStage {
  deep_ois::StabiliserFitResult fit;
  double lens_log_moved_s = 0.0;
  bool lens_log_timed = false;  // --fit-time-offset ran
};

std::string describeTarget(deep_ois::LensMotionTarget target) {
  return target == deep_ois::LensMotionTarget::kImages    ? "gyro-anchored lens shift (images)"
         : target == deep_ois::LensMotionTarget::kLensLog ? "the camera's lens-shift log"
                                                          : "simulator truth";
}

// Declares the flags and parses them; a status to exit with when the tool should not go on.
std::optional<int> parseArguments(int argc, char** argv, Arguments* args) {
  deep_ois::ToolCommandLine command_line(
      "train_stabiliser",
      "Learns a camera's optical image stabiliser from its recordings (rosbags with images, IMU, "
      "camera_info and the IMU -> camera transform): the lens motion per frame pair and row patch "
      "from the images with the gyro's rotations (gyro-anchored ground truth), then the "
      "stabiliser model fitted to it. Writes MODEL.yaml (parameters, camera, training data) and "
      "MODEL_fit.csv and MODEL_fit.png (the fit's loss curve and the kept model's residual), and "
      "keeps each recording's ground truth in a cache directory (a re-run resumes from it).",
      "Exit status: 0 done, 1 no usable recording or the fit failed, 2 usage, 3 done but some "
      "recordings could not be read, the calibration (or the lens log's clock) looks wrong or the "
      "fitted parameters are implausible.");
  CLI::App& app = command_line.app();
  const std::string package = ros::package::getPath("deep_ois");
  args->gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  app.add_option("--bags", args->bags, "training recordings")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--held-out", args->held_out_bags, "recordings scored, not trained on")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--gyro-config", args->gyro_config, "gyro flow parameters of the camera (YAML)")
      ->capture_default_str()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--out", args->out_path, "the model to write")->required()->type_name("MODEL.yaml");
  app.add_option("--name", args->name, "what the model is for (default: the camera's summary)");
  app.add_option("--cache", args->cache_dir,
                 "where each recording's ground truth is kept (default MODEL.yaml.cache); a "
                 "recording found there is not recomputed, so runs for several models can share it")
      ->type_name("DIR");
  app.add_option("--target", args->target,
                 "lens motion from the 'images' (gyro-anchored ground truth), the camera's own "
                 "lens-shift 'log' (with the gyro config's lens_shift_* convention) or the "
                 "simulator's 'truth'")
      ->check(deep_ois::oneOf({"images", "log", "truth"}))
      ->capture_default_str();
  app.add_flag("--fit-time-offset", args->fit_time_offset,
               "--target log: move the lens log by what the fit's timing check finds on the "
               "training recordings, then fit again (as lens_log_fit --fit-time-offset), and say "
               "the lens_shift_time_offset to set in the gyro config");
  command_line.addNumber("--iterations", args->fit_options.iterations,
                         "Levenberg-Marquardt iterations per candidate")
      ->check(deep_ois::atLeast(1));
  command_line.addNumber("--warm-up", args->fit_options.warm_up_s,
                         "seconds of each recording's gyro before its first scored pair")
      ->check(deep_ois::atLeast(0));
  app.add_flag("--no-progress", args->no_progress, "no progress bars");
  app.add_option("--candidate", args->forced_candidate,
                 "keep the candidate whose name contains this (e.g. soft stroke) instead of the "
                 "best on the held-out recordings, for comparisons (the check against no lens "
                 "motion still applies)");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return status;
  if (args->gyro_config.empty())
    return command_line.usageError("--gyro-config: package deep_ois not found, so give the file");
  args->lens_target = deep_ois::lensMotionTargetNamed(args->target);
  if (args->fit_time_offset && args->lens_target != deep_ois::LensMotionTarget::kLensLog)
    return command_line.usageError("--fit-time-offset moves a lens log: it needs --target log");
  args->fit_options.target = args->lens_target;
  if (args->cache_dir.empty()) args->cache_dir = args->out_path + ".cache";
  return std::nullopt;
}

// Step 1: each recording's ground truth, from the cache when it holds this bag and gyro config.
RecordingSet readRecordings(const Arguments& args, const deep_ois::GyroFlowParameters& gyro,
                            const std::vector<std::string>& paths, const char* what) {
  RecordingSet set;
  std::unique_ptr<deep_ois::ProgressBar> progress;
  if (!args.no_progress) progress = std::make_unique<deep_ois::ProgressBar>(paths.size(), what);
  std::size_t done = 0;
  for (const std::string& bag : paths) {
    const std::string cache = deep_ois::stabiliserCachePath(args.cache_dir, bag, args.target);
    // A line of its own after a bar drawn on a terminal.
    const char* newline = progress && progress->drawing() ? "\n" : "";
    try {
      const deep_ois::StabiliserCacheKey key = deep_ois::stabiliserCacheKey(bag, gyro, args.target);
      std::string stale;
      std::optional<deep_ois::StabiliserRecordingData> data =
          deep_ois::readStabiliserCache(cache, key, bag, &stale);
      const bool cached = data.has_value();
      if (!data) {
        if (stale != "no cache") {
          std::fprintf(stderr, "%strain_stabiliser: %s: cached data not used: %s\n", newline,
                       bag.c_str(), stale.c_str());
        }
        data = deep_ois::readStabiliserRecording(bag, gyro, args.lens_target);
        deep_ois::writeStabiliserCache(cache, key, bag, *data);
      }
      if (progress) progress->update(++done);
      std::fprintf(stderr, "%strain_stabiliser: %s\n", newline,
                   deep_ois::recordingSummary(bag, *data, args.lens_target, cached).c_str());
      const std::string readout = deep_ois::readoutMismatch(*data, gyro.rolling_shutter.readout_time_s);
      if (!readout.empty()) {
        set.calibration_suspect = true;
        std::fprintf(stderr, "train_stabiliser: WARNING: %s: %s\n", bag.c_str(), readout.c_str());
      }
      if (args.lens_target == deep_ois::LensMotionTarget::kImages &&
          data->median_track_residual_px > kCalibrationSuspectPx) {
        set.calibration_suspect = true;
        std::fprintf(stderr,
                     "train_stabiliser: WARNING: %s: the gyro's rotations leave %.2f px median "
                     "track residual (> %.1f px with the lens fitted): the camera-IMU calibration "
                     "(time_offset, readout_time, IMU -> camera rotation) does not fit this "
                     "recording; run calibrate on it\n",
                     bag.c_str(), data->median_track_residual_px, kCalibrationSuspectPx);
      }
      set.cameras.push_back(data->camera);
      set.recordings.push_back(std::move(data->recording));
    } catch (const std::exception& e) {
      // One unreadable recording must not lose the others.
      if (progress) progress->update(++done);
      std::fprintf(stderr, "%strain_stabiliser: %s (skipped)\n", newline, e.what());
      ++set.failures;
    }
  }
  return set;
}

// One camera, or a generic model across cameras (its file then names no camera, and the nodelet
// has nothing to compare: the parameters are in focal-length units).
bool oneCamera(const std::vector<deep_ois::CameraDescription>& cameras) {
  for (const auto& camera : cameras) {
    const std::string difference = cameras.front().differencesTo(camera);
    if (!difference.empty()) {
      std::fprintf(stderr,
                   "train_stabiliser: the recordings are of more than one camera (%s: %s vs %s): "
                   "training a generic model, which records no camera\n",
                   difference.c_str(), cameras.front().summary().c_str(), camera.summary().c_str());
      return false;
    }
  }
  return true;
}

// Step 2: the fit, with progress; with --fit-time-offset the lens log is moved onto the gyro's
// clock first (training and held-out recordings alike: the clock is the camera's).
FitStage fitModel(const Arguments& args, std::vector<deep_ois::StabiliserFitRecording>* training,
                  std::vector<deep_ois::StabiliserFitRecording>* held_out) {
  std::unique_ptr<deep_ois::ProgressBar> progress;
  if (!args.no_progress) progress = std::make_unique<deep_ois::ProgressBar>(0, "fit steps");
  const deep_ois::ProgressCallback on_progress = [&](std::size_t done, std::size_t total) {
    if (!progress) return;
    progress->setTotal(total);  // known once the fit runs; the rate counts from the start
    progress->update(done);
  };
  FitStage stage;
  if (!args.fit_time_offset) {
    stage.fit = deep_ois::fitStabiliser(*training, args.fit_options, on_progress);
  } else {
    const deep_ois::LensLogTimeFit timed = deep_ois::fitStabiliserAndLensLogTime(
        [&](double moved_s) { return deep_ois::withLensLogMoved(*training, moved_s); }, args.fit_options,
        on_progress);
    stage.fit = timed.fit;
    stage.lens_log_timed = true;
    stage.lens_log_moved_s = timed.moved_s;
    *training = deep_ois::withLensLogMoved(*training, timed.moved_s);
    *held_out = deep_ois::withLensLogMoved(*held_out, timed.moved_s);
  }
  for (const std::string& line : stage.fit.log)
    std::fprintf(stderr, "train_stabiliser: fit: %s\n", line.c_str());
  return stage;
}

// What the report warns about: the fit's review applies only when the model written is the fit
// (a refused fit's gain or timing describe no model written), with the causes of the target in use
// (StabiliserFitOptions::target).
struct Findings {
  std::vector<std::string> on_bound, implausible, timing;
  bool calibration_suspect = false;
};
Findings reviewKept(const Arguments& args, const FitStage& stage,
                    const deep_ois::StabiliserTrainingChoice& choice, bool recordings_suspect) {
  Findings findings;
  findings.calibration_suspect = recordings_suspect;
  if (choice.keptNoLensMotion()) return findings;
  findings.on_bound = stage.fit.review.on_bound;
  findings.implausible = deep_ois::reviewStabiliserFit(choice.keptParameters(), args.lens_target).implausible;
  findings.timing = stage.fit.review.timing;
  if (!findings.timing.empty()) findings.calibration_suspect = true;
  for (const std::string& line : findings.on_bound)
    std::fprintf(stderr, "train_stabiliser: note: %s\n", line.c_str());
  for (const std::string& line : findings.implausible)
    std::fprintf(stderr, "train_stabiliser: WARNING: implausible %s\n", line.c_str());
  // The lens absorbs timing errors (the track residual stays small): the fit's timing check.
  for (const std::string& line : findings.timing)
    std::fprintf(stderr, "train_stabiliser: WARNING: %s\n", line.c_str());
  return findings;
}

// Step 3: the model file (parameters, camera, training data and scores).
deep_ois::StabiliserModelFile describeModel(const Arguments& args, const FitStage& stage,
                                            const deep_ois::StabiliserTrainingChoice& choice,
                                            const RecordingSet& training, std::size_t training_count,
                                            const deep_ois::StabiliserScore& held_out_score) {
  deep_ois::StabiliserModelFile model;
  model.parameters = choice.keptParameters();
  const bool one_camera = oneCamera(training.cameras);
  if (one_camera) model.camera = training.cameras.front();
  model.name = args.name.empty() ? (one_camera ? model.camera.summary() : "generic") : args.name;
  model.training.target = describeTarget(args.lens_target);
  model.training.data_files = args.bags;
  model.training.recordings = training_count;
  model.training.observations = stage.fit.observations_used;
  model.training.rms_without_model_px = stage.fit.rms_without_model_px;
  model.training.rms_px = choice.keptTrainingRmsPx();
  model.training.held_out_rms_without_model_px = held_out_score.rms_without_model_px;
  model.training.held_out_rms_px = held_out_score.rms_px;
  try {
    model.training.data_sha256 = deep_ois::sha256OfFiles(args.bags);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: data hash: %s\n", e.what());
  }
  return model;
}

// MODEL_fit.png beside MODEL.yaml: the fit's loss curve and the residual of the model written.
std::string writeFitPlot(const std::string& out_path, const FitStage& stage,
                         const deep_ois::StabiliserTrainingChoice& choice) {
  std::string plot_path = out_path;
  if (plot_path.size() > 5 && plot_path.substr(plot_path.size() - 5) == ".yaml")
    plot_path.resize(plot_path.size() - 5);
  plot_path += "_fit.png";
  const deep_ois::StabiliserFitResult& fit = stage.fit;
  const std::vector<double> kept(fit.rms_history.size(), choice.keptTrainingRmsPx());
  // Short labels: the legend sits inside the chart; the report names the kept candidate.
  const std::string fitted = choice.keptNoLensMotion() ? "fit, refused" : "fit";
  const std::string written = choice.keptNoLensMotion() ? "kept: no lens motion" : "kept model";
  {
    std::vector<double> steps(fit.rms_history.size());
    std::iota(steps.begin(), steps.end(), 1.0);
    deep_ois::CsvPlot plot;
    plot.title = "train_stabiliser: fit of " + fs::path(out_path).filename().string();
    plot.x_column = "step";
    plot.x_label = "accepted Levenberg-Marquardt step (all stages of the fit)";
    plot.y_labels = {"RMS lens-motion residual [px]"};
    plot.curves = {{"rms_px", fitted}, {"kept_rms_px", written}};
    plot.log_y = true;
    const std::string csv_path = plot_path.substr(0, plot_path.size() - 4) + ".csv";
    const deep_ois::PlotOutcome outcome = deep_ois::writeAndPlotCsv(
        plot, {{"step", steps}, {"rms_px", fit.rms_history}, {"kept_rms_px", kept}}, csv_path, plot_path);
    if (!outcome.written)
      std::fprintf(stderr, "train_stabiliser: %s\n", deep_ois::describePlot(outcome, csv_path, plot_path).c_str());
  }
  return plot_path;
}

// Step 4: the report on stdout: the model written and why, the candidates, the lens-motion
// residuals, and the warnings that apply to it.
void printReport(const Arguments& args, const deep_ois::StabiliserModelFile& model, const std::string& plot_path,
                 const FitStage& stage, const deep_ois::StabiliserTrainingChoice& choice,
                 const std::vector<deep_ois::LensMotionScoreRow>& rows, const Findings& findings,
                 double config_lens_time_offset_s) {
  const auto& p = model.parameters;
  std::printf("Stabiliser model %s (%s); fit curve %s\n\n", args.out_path.c_str(), model.name.c_str(),
              plot_path.c_str());
  std::printf("%s\n\n", deep_ois::keptModelReason(choice).c_str());
  if (choice.keptNoLensMotion()) {
    // The chain's other fields mean nothing at gain 0 (and the fit's bounds are not this model's).
    std::printf("Parameters: gain 0, the lens does not move (the compensation is the plain gyro).\n\n");
  } else {
    std::printf("%s\n", deep_ois::stabiliserParameterTable(p, stage.fit.review).c_str());
  }
  std::printf("Candidates, lens-motion RMS residual (pixels):\n\n%s\n", deep_ois::candidateTable(choice).c_str());
  std::printf("Lens motion per frame pair and row patch, RMS residual (pixels):\n\n");
  std::printf("%s", deep_ois::lensMotionTable(rows).c_str());
  if (stage.lens_log_timed) {
    if (stage.lens_log_moved_s != 0.0) {
      std::printf("\nThe lens log was moved by %+.1f ms to fit the gyro (the timing check on the training "
                  "recordings). Set %s in the gyro config.\n",
                  1e3 * stage.lens_log_moved_s,
                  deep_ois::lensShiftTimeOffsetAdvice(config_lens_time_offset_s, stage.lens_log_moved_s).c_str());
    } else {
      std::printf("\n--fit-time-offset: the lens log was not moved (the timing check did not run: the "
                  "lens hardly follows the rotation).\n");
    }
  }
  std::printf("\ntrained in %.1f s (ground truth included; cached recordings are not recomputed)\n",
              model.training.training_time_s);
  if (findings.calibration_suspect) {
    if (args.lens_target == deep_ois::LensMotionTarget::kLensLog && !findings.timing.empty()) {
      std::printf("\nWARNING: the lens log's timing does not fit the gyro (see above): the model is only as "
                  "good as the log's clock; set lens_shift_time_offset as said, or run with "
                  "--fit-time-offset.\n");
    } else {
      std::printf("\nWARNING: the calibration does not fit some recordings (see above): the model is "
                  "only as good as the gyro's rotations; run calibrate and train again.\n");
    }
    for (const std::string& line : findings.timing) std::printf("- %s\n", line.c_str());
  }
  if (!findings.on_bound.empty()) {
    std::printf("\nParameters on a bound of the fit (the data wanted them further):\n");
    for (const std::string& line : findings.on_bound) std::printf("- %s\n", line.c_str());
  }
  if (!findings.implausible.empty()) {
    std::printf("\nWARNING: implausible parameters, the model is likely wrong:\n");
    for (const std::string& line : findings.implausible) std::printf("- %s\n", line.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  Arguments args;
  if (const std::optional<int> status = parseArguments(argc, argv, &args)) return *status;
  try {  // now, not after the fit: a mistyped --out folder must not cost the fit
    deep_ois::StabiliserModelFile::checkSavable(args.out_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: --out: %s\n", e.what());
    return 2;
  }
  const auto started = std::chrono::steady_clock::now();
  deep_ois::GyroFlowParameters gyro;
  try {
    gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(args.gyro_config));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s: %s\n", args.gyro_config.c_str(), e.what());
    return 2;
  }
  std::error_code ignored;
  fs::create_directories(args.cache_dir, ignored);

  // 1. Ground truth per recording (cached).
  RecordingSet training = readRecordings(args, gyro, args.bags, "recordings");
  RecordingSet held_out = readRecordings(args, gyro, args.held_out_bags, "held-out recordings");
  if (training.recordings.empty()) {
    std::fprintf(stderr, "train_stabiliser: no training recording could be read\n");
    return 1;
  }

  // 2. The fit, the candidates and the final rule (the best candidate, checked against no lens
  // motion on data it was not fitted to).
  args.fit_options.readout_time_s = gyro.rolling_shutter.readout_time_s;  // for its timing check
  FitStage stage;
  deep_ois::StabiliserTrainingChoice choice;
  try {
    stage = fitModel(args, &training.recordings, &held_out.recordings);
    choice = deep_ois::chooseTrainedStabiliser(stage.fit, training.recordings, held_out.recordings,
                                               args.fit_options, args.forced_candidate, args.kinds);
  } catch (const std::invalid_argument& e) {
    if (!args.forced_candidate.empty() && std::string(e.what()).rfind("--candidate", 0) == 0) {
      std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
      return 2;
    }
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "train_stabiliser: check against no lens motion %s\n", choice.lens_check.reason.c_str());
  const Findings findings =
      reviewKept(args, stage, choice, training.calibration_suspect || held_out.calibration_suspect);

  // 3. Held-out scores and the model file.
  const deep_ois::StabiliserModel kept = choice.keptParameters();
  const deep_ois::StabiliserScore score =
      deep_ois::scoreStabiliser(kept, held_out.recordings, args.fit_options);
  deep_ois::StabiliserModelFile model =
      describeModel(args, stage, choice, training, training.recordings.size(), score);
  model.training.training_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  try {
    model.save(args.out_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_stabiliser: %s\n", e.what());
    return 1;
  }
  const std::string plot_path = writeFitPlot(args.out_path, stage, choice);

  // 4. The report.
  const deep_ois::StabiliserFitResult& fit = stage.fit;
  std::vector<deep_ois::LensMotionScoreRow> rows = {
      {"training", training.recordings.size(), fit.observations_used, fit.rms_without_model_px,
       choice.keptTrainingRmsPx()}};
  if (!held_out.recordings.empty()) {
    rows.push_back({"held out", held_out.recordings.size(), score.observations, score.rms_without_model_px,
                    score.rms_px});
  }
  printReport(args, model, plot_path, stage, choice, rows, findings, gyro.lens_shift_convention.time_offset_s);
  const bool implausible = !findings.implausible.empty();
  return training.failures + held_out.failures > 0 || findings.calibration_suspect || implausible ? 3 : 0;
}
