// Scores recordings with annotated correspondences and prints the paper's table: mean geometry
// distance |p_a + flow(p_a) - p_b| per category and method, each pair capped at its identity
// error, a method without an estimate scored as identity, Avg = mean of the category means.
// Flags: --help.
//
// Exit status: 0; 1 unusable input; 2 bad flags; 3 a recording could not be scored (the table
// holds the others); 4 the recorded live flows disagree with the offline ones.
//
// Rows: identity; SIFT / ORB / AKAZE + RANSAC / MAGSAC (one global homography); the gyro on the
// non-OIS camera (the simulator's twins) and on the OIS camera, uncompensated; the global F and
// Fundamental Mixtures ground truths; then the model, named by its file (the compensation nodelet's network
// on the gyro flow nodelet's flow), the stabiliser models and, with --oracle, the oracle of each
// stabiliser design given (its own simulator controller on the camera's gyro). With --recorded, the gyro_flow and compensated_flow messages
// the live nodelets published during a replay of the same bags (rosbag record) are scored too, as
// rows of their own: they must equal the offline rows. The work is EvaluationRunner's
// (tools/support/evaluation_runner.h); this file parses flags and writes the outputs.
#include <ros/package.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/evaluation/stabiliser_table_row.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/core/sim/simulator_config.h"
#ifdef DEEP_OIS_WITH_TORCH
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#endif
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/evaluation_runner.h"
#include "deep_ois/tools/support/recorded_flows.h"
#include "deep_ois/tools/support/stabiliser_oracle_row.h"

#ifdef DEEP_OIS_WITH_TORCH
namespace {

// The model's row, named by its file so that a table says which model it scored (e.g.
// "DeepOIS, fast.pt (preset fast)").
std::string modelRowName(const std::string& model_path, const std::string& preset) {
  return "DeepOIS, " + std::filesystem::path(model_path).filename().string() + " (preset " +
         preset + ")";
}

}  // namespace
#endif

constexpr char kDescription[] =
    "Scores recordings with annotated correspondences and prints the paper's table: mean geometry "
    "distance |p_a + flow(p_a) - p_b| in pixels per category and method, each pair capped at its "
    "identity error, a method without an estimate scored as identity, Avg = mean of the category "
    "means. Rows: identity; SIFT / ORB / AKAZE + RANSAC / MAGSAC; the gyro on the non-OIS and the "
    "OIS camera, uncompensated; the global F and Fundamental Mixtures ground truths; the shipped "
    "model; the stabiliser models; with --oracle, a stabiliser design's own simulator controller "
    "on the camera's gyro. With --recorded, the flows the live nodelets published during a replay of the same "
    "bags "
    "are scored too and must equal the offline rows. --out writes evaluation.csv, evaluation.json, "
    "evaluation_pairs.csv, bar charts and ghost images.";
constexpr char kFooter[] =
    "Exit status: 0; 1 unusable input; 2 bad flags; 3 a recording could not be scored (the table\n"
    "holds the others); 4 the recorded live flows disagree with the offline ones.";

int main(int argc, char** argv) {
  deep_ois::EvaluationOptions options;
  deep_ois::StandardMethodOptions standard;
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  std::string out_dir, annotations, camera, recorded;
  std::string model_path = package.empty() ? "" : package + "/models/fast.pt";
  int torch_threads = 1;
  bool no_image_baselines = false, no_ground_truth = false, no_model = false, no_progress = false;
  deep_ois::ToolCommandLine command_line("evaluate", kDescription, kFooter);
  CLI::App& app = command_line.app();
  app.add_option("--bags", options.bags,
                 "the recordings (simulator bags, or recordings with --annotations)")
      ->required()
      ->type_name("FILE.bag");
  app.add_option("--out", out_dir, "write the table, the pairs, plots and ghost images here")
      ->type_name("DIR");
  app.add_option(
         "--gyro-config", gyro_config,
         "the gyro flow nodelet's parameters (default: the package's config/gyro_flow.yaml)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--annotations", annotations,
                 "point correspondences of recordings without simulator truth")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.csv");
  app.add_option("--camera", camera, "which gyro row the --annotations recordings belong to")
      ->check(deep_ois::oneOf({"ois", "non-ois"}))
      ->type_name("ois|non-ois");
  command_line
      .addNumber("--ghost-pairs", options.ghost_pairs_per_category,
                 "ghost images per category (0: none)")
      ->check(deep_ois::atLeast(0));
  command_line
      .addNumber("--ghost-zoom", options.ghost_zoom,
                 "ghost panels show the centre 1/N of the frame magnified N times (1: whole frame)")
      ->check(deep_ois::atLeast(0));
  command_line.addNumber("--max-pairs", options.max_pairs_per_bag,
                         "score only the first pairs of each bag (0: all)");
  app.add_flag("--no-image-baselines", no_image_baselines, "leave out the SIFT / ORB / AKAZE rows");
  app.add_flag("--no-ground-truth", no_ground_truth,
               "leave out the global F and Fundamental Mixtures rows");
  app.add_flag("--no-progress", no_progress, "no progress bar");
  CLI::Option* model_option =
      app.add_option("--model", model_path,
                     "the model row's network (default: the package's models/fast.pt)")
          ->check(deep_ois::existingFile())
          ->type_name("FILE.pt");
  app.add_flag("--no-model", no_model, "leave out the model row")->excludes(model_option);
  // The shipped default compensator: the generic learned stabiliser model.
  const std::string shipped_stabiliser =
      package.empty() ? "" : package + "/models/stabiliser_generic.yaml";
  std::vector<std::string> stabiliser_paths;
  CLI::Option* stabiliser_option =
      app.add_option("--stabiliser", stabiliser_paths,
                     "learned stabiliser models (train_stabiliser), one row each (default: the "
                     "package's models/stabiliser_generic.yaml)")
          ->check(deep_ois::existingFile())
          ->type_name("FILE.yaml ...");
  bool no_stabiliser = false;
  app.add_flag("--no-stabiliser", no_stabiliser, "leave out the stabiliser model rows")
      ->excludes(stabiliser_option);
  // The oracle of a stabiliser design: its own simulator controller on the camera's gyro.
  std::vector<std::string> oracle_designs;
  CLI::Option* oracle_option =
      app.add_option("--oracle", oracle_designs,
                     "stabiliser designs (simulator module overlays, e.g. "
                     "config/simulator/modules/X.yaml) whose own controller and lens loop, with "
                     "their parameters, are run on the recordings' gyro and scored as a "
                     "compensation row each: the best a model of that design can do from the "
                     "camera's gyro")
          ->check(deep_ois::existingFile())
          ->type_name("MODULE.yaml ...");
  std::string oracle_base = package.empty() ? "" : package + "/config/simulator/RE.yaml";
  app.add_option("--oracle-base", oracle_base,
                 "the simulator config the --oracle overlays go over (default: the package's "
                 "config/simulator/RE.yaml; only its ois and sensor sections matter)")
      ->check(deep_ois::existingFile())
      ->type_name("CONFIG.yaml")
      ->needs(oracle_option);
  // By default the oracle starts at each recording's first gyro sample, as the stabiliser model
  // rows do. The simulator starts its stabiliser earlier (kSimulatorMarginS before the first
  // frame, before its IMU starts); starting the oracle then with the first sample held back to it
  // measured worse on 5 of 6 modules (docs/stabiliser_model.md), so it is a choice, not the default.
  double oracle_start_s = std::numeric_limits<double>::quiet_NaN();
  command_line
      .addNumber("--oracle-start", oracle_start_s,
                 "start the --oracle designs' stabilisers, centred and at rest, this many seconds "
                 "before each recording's first scored frame (the simulator starts its own 0.25 s "
                 "before), the gyro held at its first sample until it has one (default: at the "
                 "first gyro sample, as the stabiliser model rows)")
      ->default_str("")
      ->check(deep_ois::atLeast(0.0))
      ->needs(oracle_option);
  std::string live_model;
  app.add_option("--live-model", live_model,
                 "with --recorded: the model the live compensation ran (default: the package's "
                 "models/stabiliser_generic.yaml, the launch files' default); its offline row is "
                 "compared with the recorded flows")
      ->type_name("FILE");
  command_line.addNumber("--torch-threads", torch_threads, "torch threads of the model row")
      ->check(deep_ois::atLeast(1));
  app.add_option("--recorded", recorded,
                 "rosbag record of the live nodelets' gyro_flow and compensated_flow")
      ->check(deep_ois::existingFile())
      ->type_name("LIVE.bag");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (stabiliser_option->count() == 0 && !no_stabiliser && !shipped_stabiliser.empty() &&
      std::filesystem::exists(shipped_stabiliser)) {
    stabiliser_paths.push_back(shipped_stabiliser);
  }
  if (live_model.empty()) live_model = shipped_stabiliser;
  const bool live_stabiliser = deep_ois::isStabiliserModelPath(live_model);
  const std::string live_stabiliser_row =
      "stabiliser model, " + std::filesystem::path(live_model).filename().string();
  if (!recorded.empty() && live_stabiliser &&
      std::find(stabiliser_paths.begin(), stabiliser_paths.end(), live_model) ==
          stabiliser_paths.end()) {
    stabiliser_paths.push_back(live_model);  // the offline row the live flows are compared with
  }
  standard.image_baselines = !no_image_baselines;
  standard.ground_truth = !no_ground_truth;
  options.show_progress = !no_progress;
  if (no_model) model_path.clear();
  if (gyro_config.empty()) {
    return command_line.usageError(
        "package deep_ois not found (source its setup.bash), so pass --gyro-config");
  }
  if (!camera.empty() && annotations.empty()) {
    return command_line.usageError("--camera applies to --annotations recordings only");
  }
  // The compensation rows score an OIS camera's pairs only: asked for on recordings said to be of
  // a camera without OIS they would be empty, so an explicit request is refused, not dropped.
  if (camera == "non-ois") {
    for (CLI::Option* option : {stabiliser_option, model_option, oracle_option}) {
      if (option->count() == 0) continue;
      return command_line.usageError(
          option->get_name() +
          ": its rows compensate an OIS camera and score only its pairs, "
          "but --camera non-ois says these recordings are of a camera without OIS; pass --camera "
          "ois to score the model on them anyway (what it does to a camera without OIS)");
    }
  }
  if (camera == "ois") {
    options.annotated_scope = deep_ois::kOisCameraPairs;
  } else if (camera == "non-ois") {
    options.annotated_scope = deep_ois::kNonOisCameraPairs;
  }

  deep_ois::EvaluationReport report;
  bool parity_failed = false;
  // Each model row with the camera it was trained for, compared with the recordings' after the run.
  std::vector<std::pair<std::string, deep_ois::CameraDescription>> model_cameras;
#ifdef DEEP_OIS_WITH_TORCH
  std::unique_ptr<deep_ois::CompensationModel> model;
#else
  // Built without libtorch: only an explicit --model is an error, the default row is left out.
  if (model_option->count() > 0) {
    return command_line.usageError(
        "--model: this build has no compensation network (built without libtorch)");
  }
  model_path.clear();
  const std::unique_ptr<int> model;  // no model row
#endif
  try {
    options.gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
    if (!annotations.empty()) options.annotations = deep_ois::readAnnotationFile(annotations);
    // The ground truth must describe the gyro's row patches.
    standard.solver.patch_count = options.gyro.rolling_shutter.patch_count;
    deep_ois::EvaluationRunner runner(options);
    runner.addMethods(deep_ois::standardAlignmentMethods(standard));
    // The camera's own lens log, when the recordings have one: the exact OIS motion, no network.
    if (deep_ois::recordingsHaveLensShiftLog(options)) runner.addMethod(deep_ois::gyroLensLogMethod());
    // The shipped model: the compensation nodelet's network on the gyro flow nodelet's flow, over
    // each recording's pairs in order with the motion history, as the nodelet runs it.
#ifdef DEEP_OIS_WITH_TORCH
    if (!model_path.empty()) {
      deep_ois::setTorchThreads(torch_threads);
      model = std::make_unique<deep_ois::CompensationModel>(
          deep_ois::CompensationModel::load(model_path));
      const std::string model_row = modelRowName(model_path, model->metadata().preset);
      model_cameras.emplace_back(model_row, model->metadata().camera);
      auto stream = std::make_shared<deep_ois::CompensationStream>(*model);
      auto recording = std::make_shared<std::uint64_t>(0);
      runner.addMethod({model_row,
                        deep_ois::kOisCameraPairs,
                        [stream, recording](const deep_ois::FramePairContext& pair) {
                          if (pair.recording_id != *recording) stream->reset();
                          *recording = pair.recording_id;
                          return deep_ois::AlignmentEstimate::gridFlow(stream->compensate(
                              pair.gyro_flow_grid, pair.stamp_a_ns, pair.stamp_b_ns));
                        }});
    }
#else
    (void)torch_threads;
#endif
    // Learned stabiliser models: their state carried over each recording's gyro stream.
    for (const std::string& path : stabiliser_paths) {
      const deep_ois::StabiliserModelFile file = deep_ois::StabiliserModelFile::load(path);
      const std::string row = "stabiliser model, " + std::filesystem::path(path).filename().string();
      runner.addMethod(deep_ois::stabiliserAlignmentMethod(row, file.parameters));
      model_cameras.emplace_back(row, file.camera);
    }
    // Stabiliser oracles: each design's own controller driven by the recordings' gyro.
    for (const std::string& path : oracle_designs) {
      if (oracle_base.empty()) {
        throw std::runtime_error("--oracle: package deep_ois not found, so pass --oracle-base");
      }
      const deep_ois::sim::SimulatorConfig design =
          deep_ois::sim::loadSimulatorConfig(oracle_base, {path});
      runner.addMethod(deep_ois::stabiliserOracleMethod(
          "oracle, " + std::filesystem::path(path).filename().string() +
              " controller on the camera gyro",
          design, oracle_start_s));
    }
    // Replay parity: what the live nodelets published, looked up by the pair's two stamps.
    std::map<deep_ois::FramePairStamps, deep_ois::RecordedFlow> live_gyro, live_compensated;
    if (!recorded.empty()) {
      live_gyro = deep_ois::readRecordedFlows(recorded, "/deep_ois/gyro_flow");
      live_compensated = deep_ois::readRecordedFlows(recorded, "/deep_ois/compensated_flow");
      // The gyro row is scored on the recorded homographies (as the offline gyro row); the
      // compensation's on the recorded grid flow for a network (as its offline row) and on the
      // recorded per-patch homographies for a stabiliser model (as its offline row): like with
      // like, so they must agree.
      auto recordedMethod =
          [](const std::map<deep_ois::FramePairStamps, deep_ois::RecordedFlow>& flows,
             bool use_homographies) {
            return [&flows, use_homographies](const deep_ois::FramePairContext& pair) {
              const auto found = flows.find({pair.stamp_a_ns, pair.stamp_b_ns});
              if (found == flows.end())
                return deep_ois::AlignmentEstimate::failed("not in the recording");
              return use_homographies
                         ? deep_ois::AlignmentEstimate::patchHomographies(
                               found->second.homographies)
                         : deep_ois::AlignmentEstimate::gridFlow(found->second.grid_flow);
            };
          };
      runner.addMethod({"gyro, OIS camera (live nodelet, recorded)", deep_ois::kOisCameraPairs,
                        recordedMethod(live_gyro, true)});
      runner.addMethod({"compensation (live nodelets, recorded)", deep_ois::kOisCameraPairs,
                        recordedMethod(live_compensated, live_stabiliser)});
    }
    report = runner.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evaluate: %s\n", e.what());
    return 1;
  }

  for (const deep_ois::RecordingOutcome& recording : report.recordings) {
    if (!recording.error.empty()) {
      std::fprintf(stderr, "evaluate: %s (not scored)\n", recording.error.c_str());
      continue;
    }
    std::string skipped;
    for (const auto& [reason, count] : recording.skip_reasons) {
      skipped += ", " + std::to_string(count) + " skipped (" + reason + ")";
    }
    std::fprintf(stderr, "evaluate: %s: %zu pairs%s\n", recording.path.c_str(),
                 recording.pairs_scored, skipped.c_str());
  }
  for (const std::string& error : report.errors)
    std::fprintf(stderr, "evaluate: %s\n", error.c_str());
  for (const std::string& row : report.rowsWithoutPairs()) {
    std::fprintf(stderr,
                 "evaluate: %s: left out, no pair in its scope (it compensates an OIS camera%s)\n",
                 row.c_str(),
                 camera == "non-ois" ? "; --camera non-ois: pass --camera ois to score it" : "");
  }
  for (const auto& [row, camera] : model_cameras) {
    std::fprintf(stderr, "evaluate: %s\n", deep_ois::modelCameraNote(row, camera, report.recordings).c_str());
  }
  std::fprintf(
      stderr,
      "evaluate: %.1f s; reading the bags %.1f s (a thread reading ahead, overlapping); methods:",
      report.elapsed_s, report.reading_s);
  for (const auto& [method, seconds] : report.method_s)
    std::fprintf(stderr, " %s %.1f s;", method.c_str(), seconds);
  std::fprintf(stderr, "\n");

  if (report.table.methods().empty()) {
    std::fprintf(stderr, "evaluate: no frame pair could be scored\n");
    return 1;
  }
  std::printf("%s", report.markdown().c_str());
  if (!recorded.empty()) {
    // Replay parity: the live nodelets' flows against the same computation offline, pair by pair.
    constexpr double kParityTolerancePx = 1e-3;
#ifdef DEEP_OIS_WITH_TORCH
    const std::string model_row =
        model ? modelRowName(model_path, model->metadata().preset) : "";
#else
    const std::string model_row;
#endif
    std::vector<std::pair<std::string, std::string>> comparisons = {
        {"gyro, OIS camera (uncompensated)", "gyro, OIS camera (live nodelet, recorded)"}};
    if (live_stabiliser) {
      comparisons.push_back({live_stabiliser_row, "compensation (live nodelets, recorded)"});
    } else if (model) {
      comparisons.push_back({model_row, "compensation (live nodelets, recorded)"});
    }
    std::printf("\nreplay parity (live nodelets recorded in %s vs offline):\n", recorded.c_str());
    for (const auto& [offline, live] : comparisons) {
      const deep_ois::MethodAgreement agreement = deep_ois::compareMethods(report, offline, live);
      const bool agrees =
          agreement.pairs_compared > 0 && agreement.max_abs_difference_px <= kParityTolerancePx;
      std::printf(
          "- %s: %zu pairs compared, largest difference %.6f px, %zu not in the recording: %s\n",
          live.c_str(), agreement.pairs_compared, agreement.max_abs_difference_px,
          agreement.missing_in_second, agrees ? "same numbers" : "DIFFERENT");
      if (!agrees) parity_failed = true;
    }
  }
  std::fflush(stdout);
  if (!out_dir.empty()) {
    try {
      const std::vector<std::string> written = deep_ois::writeEvaluationReport(report, out_dir);
      std::fprintf(stderr, "evaluate: wrote %zu files to %s\n", written.size(), out_dir.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evaluate: %s\n", e.what());
      return 1;
    }
  }
  // The table above holds every recording that could be read; say that some could not.
  if (parity_failed) return 4;
  return report.complete() ? 0 : 3;
}
