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
// stabiliser design given (its own simulator controller on the camera's gyro); the fused motion
// (the first stabiliser model's compensation on an OIS camera, the plain gyro on one without,
// refined per row patch by the pair's tracks). With --recorded, the gyro_flow and compensated_flow messages
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
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/evaluation/fused_table_row.h"
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

namespace {

// Every flag's value, and the options whose presence matters after parsing.
struct EvaluateFlags {
  deep_ois::EvaluationOptions options;
  deep_ois::StandardMethodOptions standard;
  std::string gyro_config, out_dir, annotations, camera, recorded, model_path, live_model;
  std::string shipped_stabiliser;  // the package's models/stabiliser_generic.yaml
  std::vector<std::string> stabiliser_paths, oracle_designs;
  std::string oracle_base;
  double oracle_start_s = std::numeric_limits<double>::quiet_NaN();
  int torch_threads = 1;
  bool no_image_baselines = false, no_ground_truth = false, no_model = false, no_progress = false;
  bool no_stabiliser = false, no_fusion = false;
  CLI::Option* model_option = nullptr;
  CLI::Option* stabiliser_option = nullptr;
  CLI::Option* oracle_option = nullptr;
  // Set by resolveFlags: the model the live compensation ran is a stabiliser model (not a
  // network), and its offline row.
  bool live_stabiliser = false;
  std::string live_stabiliser_row;
};

// What the run leaves for the report: the rows' models and the recorded live flows, which the
// rows reference, so they live as long as the runner.
struct EvaluationRows {
#ifdef DEEP_OIS_WITH_TORCH
  std::unique_ptr<deep_ois::CompensationModel> model;
#else
  std::unique_ptr<int> model;  // built without libtorch: no model row
#endif
  std::string model_row;  // the network's row, empty without one
  // Each model row with the camera it was trained for, compared with the recordings' after the run.
  std::vector<std::pair<std::string, deep_ois::CameraDescription>> model_cameras;
  // The fused rows' tallies (refined pairs, corrections, cost), by row.
  std::vector<std::pair<std::string, std::shared_ptr<deep_ois::FusionTally>>> fusion_tallies;
  // Replay parity: what the live nodelets published, looked up by the pair's two stamps.
  std::map<deep_ois::FramePairStamps, deep_ois::RecordedFlow> live_gyro, live_compensated;
};

#ifdef DEEP_OIS_WITH_TORCH
// The model's row, named by its file so that a table says which model it scored (e.g.
// "DeepOIS, fast.pt (preset fast)").
std::string modelRowName(const std::string& model_path, const std::string& preset) {
  return "DeepOIS, " + std::filesystem::path(model_path).filename().string() + " (preset " +
         preset + ")";
}
#endif

constexpr char kDescription[] =
    "Scores recordings with annotated correspondences and prints the paper's table: mean geometry "
    "distance |p_a + flow(p_a) - p_b| in pixels per category and method, each pair capped at its "
    "identity error, a method without an estimate scored as identity, Avg = mean of the category "
    "means. Rows: identity; SIFT / ORB / AKAZE + RANSAC / MAGSAC; the gyro on the non-OIS and the "
    "OIS camera, uncompensated; the global F and Fundamental Mixtures ground truths; the shipped "
    "model; the stabiliser models; the fused motion (the first stabiliser model, or the gyro on a camera "
    "without OIS, refined by the pair's tracks); with --oracle, a stabiliser design's own simulator controller "
    "on the camera's gyro. With --recorded, the flows the live nodelets published during a replay of the same "
    "bags "
    "are scored too and must equal the offline rows. --out writes evaluation.csv, evaluation.json, "
    "evaluation_pairs.csv, bar charts and ghost images.";
constexpr char kFooter[] =
    "Exit status: 0; 1 unusable input; 2 bad flags; 3 a recording could not be scored (the table\n"
    "holds the others); 4 the recorded live flows disagree with the offline ones.";

void addFlags(deep_ois::ToolCommandLine& command_line, EvaluateFlags& flags) {
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  const std::string package = ros::package::getPath("deep_ois");
  flags.gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  flags.model_path = package.empty() ? "" : package + "/models/fast.pt";
  // The shipped default compensator: the generic learned stabiliser model.
  flags.shipped_stabiliser = package.empty() ? "" : package + "/models/stabiliser_generic.yaml";
  flags.oracle_base = package.empty() ? "" : package + "/config/simulator/RE.yaml";
  deep_ois::EvaluationOptions& options = flags.options;
  CLI::App& app = command_line.app();
  app.add_option("--bags", options.bags,
                 "the recordings (simulator bags, or recordings with --annotations)")
      ->required()
      ->type_name("FILE.bag");
  app.add_option("--out", flags.out_dir, "write the table, the pairs, plots and ghost images here")
      ->type_name("DIR");
  app.add_option(
         "--gyro-config", flags.gyro_config,
         "the gyro flow nodelet's parameters (default: the package's config/gyro_flow.yaml)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--annotations", flags.annotations,
                 "point correspondences of recordings without simulator truth")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.csv");
  app.add_option("--camera", flags.camera, "which gyro row the --annotations recordings belong to")
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
  app.add_flag("--no-image-baselines", flags.no_image_baselines, "leave out the SIFT / ORB / AKAZE rows");
  app.add_flag("--no-ground-truth", flags.no_ground_truth,
               "leave out the global F and Fundamental Mixtures rows");
  app.add_flag("--no-progress", flags.no_progress, "no progress bar");
  flags.model_option =
      app.add_option("--model", flags.model_path,
                     "the model row's network (default: the package's models/fast.pt)")
          ->check(deep_ois::existingFile())
          ->type_name("FILE.pt");
  app.add_flag("--no-model", flags.no_model, "leave out the model row")->excludes(flags.model_option);
  flags.stabiliser_option =
      app.add_option("--stabiliser", flags.stabiliser_paths,
                     "learned stabiliser models (train_stabiliser), one row each (default: the "
                     "package's models/stabiliser_generic.yaml)")
          ->check(deep_ois::existingFile())
          ->type_name("FILE.yaml ...");
  app.add_flag("--no-stabiliser", flags.no_stabiliser, "leave out the stabiliser model rows")
      ->excludes(flags.stabiliser_option);
  app.add_flag("--no-fusion", flags.no_fusion,
               "leave out the fused rows (the first stabiliser model's compensation, or the gyro on a camera "
               "without OIS, refined by the pair's tracks; docs/fusion.md)");
  // The oracle of a stabiliser design: its own simulator controller on the camera's gyro.
  flags.oracle_option =
      app.add_option("--oracle", flags.oracle_designs,
                     "stabiliser designs (simulator module overlays, e.g. "
                     "config/simulator/modules/X.yaml) whose own controller and lens loop, with "
                     "their parameters, are run on the recordings' gyro and scored as a "
                     "compensation row each: the best a model of that design can do from the "
                     "camera's gyro")
          ->check(deep_ois::existingFile())
          ->type_name("MODULE.yaml ...");
  app.add_option("--oracle-base", flags.oracle_base,
                 "the simulator config the --oracle overlays go over (default: the package's "
                 "config/simulator/RE.yaml; only its ois and sensor sections matter)")
      ->check(deep_ois::existingFile())
      ->type_name("CONFIG.yaml")
      ->needs(flags.oracle_option);
  // By default the oracle starts at each recording's first gyro sample, as the stabiliser model
  // rows do. The simulator starts its stabiliser earlier (kSimulatorMarginS before the first
  // frame, before its IMU starts); starting the oracle then with the first sample held back to it
  // measured worse on 5 of 6 modules (docs/stabiliser_model.md), so it is a choice, not the default.
  command_line
      .addNumber("--oracle-start", flags.oracle_start_s,
                 "start the --oracle designs' stabilisers, centred and at rest, this many seconds "
                 "before each recording's first scored frame (the simulator starts its own 0.25 s "
                 "before), the gyro held at its first sample until it has one (default: at the "
                 "first gyro sample, as the stabiliser model rows)")
      ->default_str("")
      ->check(deep_ois::atLeast(0.0))
      ->needs(flags.oracle_option);
  app.add_option("--live-model", flags.live_model,
                 "with --recorded: the model the live compensation ran (default: the package's "
                 "models/stabiliser_generic.yaml, the launch files' default); its offline row is "
                 "compared with the recorded flows")
      ->type_name("FILE");
  command_line.addNumber("--torch-threads", flags.torch_threads, "torch threads of the model row")
      ->check(deep_ois::atLeast(1));
  app.add_option("--recorded", flags.recorded,
                 "rosbag record of the live nodelets' gyro_flow and compensated_flow")
      ->check(deep_ois::existingFile())
      ->type_name("LIVE.bag");
}

// The defaults that depend on other flags, and the combinations refused; a usage error's exit
// status, or nothing when the flags are usable.
std::optional<int> resolveFlags(deep_ois::ToolCommandLine& command_line, EvaluateFlags& flags) {
  if (flags.stabiliser_option->count() == 0 && !flags.no_stabiliser && !flags.shipped_stabiliser.empty() &&
      std::filesystem::exists(flags.shipped_stabiliser)) {
    flags.stabiliser_paths.push_back(flags.shipped_stabiliser);
  }
  if (flags.live_model.empty()) flags.live_model = flags.shipped_stabiliser;
  flags.live_stabiliser = deep_ois::isStabiliserModelPath(flags.live_model);
  flags.live_stabiliser_row =
      "stabiliser model, " + std::filesystem::path(flags.live_model).filename().string();
  if (!flags.recorded.empty() && flags.live_stabiliser &&
      std::find(flags.stabiliser_paths.begin(), flags.stabiliser_paths.end(), flags.live_model) ==
          flags.stabiliser_paths.end()) {
    flags.stabiliser_paths.push_back(flags.live_model);  // the offline row the live flows are compared with
  }
  flags.standard.image_baselines = !flags.no_image_baselines;
  flags.standard.ground_truth = !flags.no_ground_truth;
  flags.options.show_progress = !flags.no_progress;
  if (flags.no_model) flags.model_path.clear();
  if (flags.gyro_config.empty()) {
    return command_line.usageError(
        "package deep_ois not found (source its setup.bash), so pass --gyro-config");
  }
  if (!flags.camera.empty() && flags.annotations.empty()) {
    return command_line.usageError("--camera applies to --annotations recordings only");
  }
  // The compensation rows score an OIS camera's pairs only: asked for on recordings said to be of
  // a camera without OIS they would be empty, so an explicit request is refused, not dropped.
  if (flags.camera == "non-ois") {
    for (CLI::Option* option : {flags.stabiliser_option, flags.model_option, flags.oracle_option}) {
      if (option->count() == 0) continue;
      return command_line.usageError(
          option->get_name() +
          ": its rows compensate an OIS camera and score only its pairs, "
          "but --camera non-ois says these recordings are of a camera without OIS; pass --camera "
          "ois to score the model on them anyway (what it does to a camera without OIS)");
    }
  }
  if (flags.camera == "ois") {
    flags.options.annotated_scope = deep_ois::kOisCameraPairs;
  } else if (flags.camera == "non-ois") {
    flags.options.annotated_scope = deep_ois::kNonOisCameraPairs;
  }
#ifndef DEEP_OIS_WITH_TORCH
  // Built without libtorch: only an explicit --model is an error, the default row is left out.
  if (flags.model_option->count() > 0) {
    return command_line.usageError(
        "--model: this build has no compensation network (built without libtorch)");
  }
  flags.model_path.clear();
#endif
  return std::nullopt;
}

// The gyro flow parameters and the annotation file. Throws naming the file and the problem.
void loadInputs(EvaluateFlags& flags) {
  flags.options.gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(flags.gyro_config));
  if (!flags.annotations.empty()) flags.options.annotations = deep_ois::readAnnotationFile(flags.annotations);
  // The ground truth must describe the gyro's row patches.
  flags.standard.solver.patch_count = flags.options.gyro.rolling_shutter.patch_count;
}

// The shipped model: the compensation nodelet's network on the gyro flow nodelet's flow, over
// each recording's pairs in order with the motion history, as the nodelet runs it.
void addModelRow(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags, EvaluationRows& rows) {
#ifdef DEEP_OIS_WITH_TORCH
  if (flags.model_path.empty()) return;
  deep_ois::setTorchThreads(flags.torch_threads);
  rows.model = std::make_unique<deep_ois::CompensationModel>(deep_ois::CompensationModel::load(flags.model_path));
  rows.model_row = modelRowName(flags.model_path, rows.model->metadata().preset);
  rows.model_cameras.emplace_back(rows.model_row, rows.model->metadata().camera);
  auto stream = std::make_shared<deep_ois::CompensationStream>(*rows.model);
  auto recording = std::make_shared<std::uint64_t>(0);
  runner.addMethod({rows.model_row,
                    deep_ois::kOisCameraPairs,
                    [stream, recording](const deep_ois::FramePairContext& pair) {
                      if (pair.recording_id != *recording) stream->reset();
                      *recording = pair.recording_id;
                      return deep_ois::AlignmentEstimate::gridFlow(stream->compensate(
                          pair.gyro_flow_grid, pair.stamp_a_ns, pair.stamp_b_ns));
                    }});
#else
  (void)runner, (void)flags, (void)rows;
#endif
}

// Learned stabiliser models: their state carried over each recording's gyro stream.
void addStabiliserRows(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags, EvaluationRows& rows) {
  for (const std::string& path : flags.stabiliser_paths) {
    const deep_ois::StabiliserModelFile file = deep_ois::StabiliserModelFile::load(path);
    const std::string row = "stabiliser model, " + std::filesystem::path(path).filename().string();
    runner.addMethod(deep_ois::stabiliserAlignmentMethod(row, file.parameters));
    rows.model_cameras.emplace_back(row, file.camera);
  }
}

// The fused motion: the first stabiliser model's compensation (OIS camera pairs) and the plain gyro
// (cameras without OIS) refined per row patch by the pair's tracks, each with its own copy of the
// prior's row (a stabiliser row carries its state over the recording).
void addFusedRows(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags, EvaluationRows& rows) {
  if (flags.no_fusion) return;
  auto addRow = [&](const std::string& row, deep_ois::AlignmentMethod prior) {
    auto tally = std::make_shared<deep_ois::FusionTally>();
    runner.addMethod(deep_ois::fusedAlignmentMethod(row, std::move(prior), {}, tally));
    rows.fusion_tallies.emplace_back(row, tally);
  };
  if (!flags.stabiliser_paths.empty()) {
    const std::string& path = flags.stabiliser_paths.front();
    const std::string file = std::filesystem::path(path).filename().string();
    addRow("fused: stabiliser model, " + file + " + tracks",
           deep_ois::stabiliserAlignmentMethod("prior of the fused row",
                                               deep_ois::StabiliserModelFile::load(path).parameters));
  }
  addRow("fused: gyro + tracks", deep_ois::gyroPriorMethod());
}

// Stabiliser oracles: each design's own controller driven by the recordings' gyro.
void addOracleRows(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags) {
  for (const std::string& path : flags.oracle_designs) {
    if (flags.oracle_base.empty()) {
      throw std::runtime_error("--oracle: package deep_ois not found, so pass --oracle-base");
    }
    const deep_ois::sim::SimulatorConfig design = deep_ois::sim::loadSimulatorConfig(flags.oracle_base, {path});
    runner.addMethod(deep_ois::stabiliserOracleMethod(
        "oracle, " + std::filesystem::path(path).filename().string() + " controller on the camera gyro", design,
        flags.oracle_start_s));
  }
}

// Replay parity: what the live nodelets published, as rows of their own. The gyro row is scored
// on the recorded homographies (as the offline gyro row); the compensation's on the recorded grid
// flow for a network (as its offline row) and on the recorded per-patch homographies for a
// stabiliser model (as its offline row): like with like, so they must agree.
void addRecordedRows(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags, EvaluationRows& rows) {
  if (flags.recorded.empty()) return;
  rows.live_gyro = deep_ois::readRecordedFlows(flags.recorded, "/deep_ois/gyro_flow");
  rows.live_compensated = deep_ois::readRecordedFlows(flags.recorded, "/deep_ois/compensated_flow");
  auto recordedMethod = [](const std::map<deep_ois::FramePairStamps, deep_ois::RecordedFlow>& flows,
                           bool use_homographies) {
    return [&flows, use_homographies](const deep_ois::FramePairContext& pair) {
      const auto found = flows.find({pair.stamp_a_ns, pair.stamp_b_ns});
      if (found == flows.end()) return deep_ois::AlignmentEstimate::failed("not in the recording");
      return use_homographies ? deep_ois::AlignmentEstimate::patchHomographies(found->second.homographies)
                              : deep_ois::AlignmentEstimate::gridFlow(found->second.grid_flow);
    };
  };
  runner.addMethod({"gyro, OIS camera (live nodelet, recorded)", deep_ois::kOisCameraPairs,
                    recordedMethod(rows.live_gyro, true)});
  runner.addMethod({"compensation (live nodelets, recorded)", deep_ois::kOisCameraPairs,
                    recordedMethod(rows.live_compensated, flags.live_stabiliser)});
}

// Every row in the table's order: the standard rows, the lens log's (when the recordings have
// one: the exact OIS motion, no network), the network's, the stabiliser models', the fused ones,
// the oracles' and the recorded live flows'.
void addRows(deep_ois::EvaluationRunner& runner, const EvaluateFlags& flags, EvaluationRows& rows) {
  runner.addMethods(deep_ois::standardAlignmentMethods(flags.standard));
  if (deep_ois::recordingsHaveLensShiftLog(flags.options)) runner.addMethod(deep_ois::gyroLensLogMethod());
  addModelRow(runner, flags, rows);
  addStabiliserRows(runner, flags, rows);
  addFusedRows(runner, flags, rows);
  addOracleRows(runner, flags);
  addRecordedRows(runner, flags, rows);
}

// On stderr: per recording its pairs or its error, the report's errors, the rows left out, the
// model rows' camera notes and where the time went.
void printRunSummary(const deep_ois::EvaluationReport& report, const EvaluateFlags& flags,
                     const EvaluationRows& rows) {
  for (const deep_ois::RecordingOutcome& recording : report.recordings) {
    if (!recording.error.empty()) {
      std::fprintf(stderr, "evaluate: %s (not scored)\n", recording.error.c_str());
      continue;
    }
    std::string skipped;
    for (const auto& [reason, count] : recording.skip_reasons) {
      skipped += ", " + std::to_string(count) + " skipped (" + reason + ")";
    }
    std::fprintf(stderr, "evaluate: %s: %zu pairs%s\n", recording.path.c_str(), recording.pairs_scored,
                 skipped.c_str());
  }
  for (const std::string& error : report.errors) std::fprintf(stderr, "evaluate: %s\n", error.c_str());
  for (const std::string& row : report.rowsWithoutPairs()) {
    std::fprintf(stderr, "evaluate: %s: left out, no pair in its scope (it compensates an OIS camera%s)\n",
                 row.c_str(),
                 flags.camera == "non-ois" ? "; --camera non-ois: pass --camera ois to score it" : "");
  }
  for (const auto& [row, camera] : rows.model_cameras) {
    std::fprintf(stderr, "evaluate: %s\n", deep_ois::modelCameraNote(row, camera, report.recordings).c_str());
  }
  for (const auto& [row, tally] : rows.fusion_tallies) {
    if (tally->pairs > 0) std::fprintf(stderr, "evaluate: %s: %s\n", row.c_str(), tally->summary().c_str());
  }
  std::fprintf(stderr, "evaluate: %.1f s; reading the bags %.1f s (a thread reading ahead, overlapping); methods:",
               report.elapsed_s, report.reading_s);
  for (const auto& [method, seconds] : report.method_s) std::fprintf(stderr, " %s %.1f s;", method.c_str(), seconds);
  std::fprintf(stderr, "\n");
}

// Replay parity: the live nodelets' flows against the same computation offline, pair by pair.
// Prints one line per comparison; false when one of them differs.
bool printReplayParity(const deep_ois::EvaluationReport& report, const EvaluateFlags& flags,
                       const EvaluationRows& rows) {
  constexpr double kParityTolerancePx = 1e-3;
  std::vector<std::pair<std::string, std::string>> comparisons = {
      {"gyro, OIS camera (uncompensated)", "gyro, OIS camera (live nodelet, recorded)"}};
  if (flags.live_stabiliser) {
    comparisons.push_back({flags.live_stabiliser_row, "compensation (live nodelets, recorded)"});
  } else if (rows.model) {
    comparisons.push_back({rows.model_row, "compensation (live nodelets, recorded)"});
  }
  std::printf("\nreplay parity (live nodelets recorded in %s vs offline):\n", flags.recorded.c_str());
  bool all_agree = true;
  for (const auto& [offline, live] : comparisons) {
    const deep_ois::MethodAgreement agreement = deep_ois::compareMethods(report, offline, live);
    const bool agrees = agreement.pairs_compared > 0 && agreement.max_abs_difference_px <= kParityTolerancePx;
    std::printf("- %s: %zu pairs compared, largest difference %.6f px, %zu not in the recording: %s\n",
                live.c_str(), agreement.pairs_compared, agreement.max_abs_difference_px,
                agreement.missing_in_second, agrees ? "same numbers" : "DIFFERENT");
    if (!agrees) all_agree = false;
  }
  return all_agree;
}

}  // namespace

int main(int argc, char** argv) {
  EvaluateFlags flags;
  deep_ois::ToolCommandLine command_line("evaluate", kDescription, kFooter);
  addFlags(command_line, flags);
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (const std::optional<int> status = resolveFlags(command_line, flags)) return *status;

  deep_ois::EvaluationReport report;
  EvaluationRows rows;
  try {
    loadInputs(flags);
    deep_ois::EvaluationRunner runner(flags.options);
    addRows(runner, flags, rows);
    report = runner.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evaluate: %s\n", e.what());
    return 1;
  }
  printRunSummary(report, flags, rows);
  if (report.table.methods().empty()) {
    std::fprintf(stderr, "evaluate: no frame pair could be scored\n");
    return 1;
  }
  std::printf("%s", report.markdown().c_str());
  const bool parity_failed = !flags.recorded.empty() && !printReplayParity(report, flags, rows);
  std::fflush(stdout);
  if (!flags.out_dir.empty()) {
    try {
      std::string plot_problem;
      const std::vector<std::string> written = deep_ois::writeEvaluationReport(report, flags.out_dir, &plot_problem);
      std::fprintf(stderr, "evaluate: wrote %zu files to %s\n", written.size(), flags.out_dir.c_str());
      if (!plot_problem.empty()) std::fprintf(stderr, "evaluate: %s\n", plot_problem.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evaluate: %s\n", e.what());
      return 1;
    }
  }
  // The table above holds every recording that could be read; say that some could not.
  if (parity_failed) return 4;
  return report.complete() ? 0 : 3;
}
