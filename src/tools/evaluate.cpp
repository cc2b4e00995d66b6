// Scores recordings with annotated correspondences and prints the paper's table: mean geometry
// distance |p_a + flow(p_a) - p_b| per category and method, each pair capped at its identity
// error, a method without an estimate scored as identity, Avg = mean of the category means.
//
//   evaluate --bags a.bag [b.bag ...] [--out DIR] [--gyro-config config/gyro_flow.yaml]
//            [--annotations FILE.csv [--camera ois|non-ois]] [--ghost-pairs N] [--ghost-zoom N]
//            [--max-pairs N] [--no-image-baselines] [--no-ground-truth] [--no-progress]
//            [--model models/fast.pt | --no-model] [--torch-threads 1] [--recorded LIVE.bag]
//
// Exit status: 0; 1 unusable input; 2 bad flags; 3 a recording could not be scored (the table
// holds the others); 4 the recorded live flows disagree with the offline ones.
//
// Rows: identity; SIFT / ORB / AKAZE + RANSAC / MAGSAC (one global homography); the gyro on the
// non-OIS camera (the simulator's twins) and on the OIS camera, uncompensated; the global F and
// Fundamental Mixtures ground truths; then the shipped model (the compensation nodelet's network
// on the gyro flow nodelet's flow). With --recorded, the gyro_flow and compensated_flow messages
// the live nodelets published during a replay of the same bags (rosbag record) are scored too, as
// rows of their own: they must equal the offline rows. The work is EvaluationRunner's
// (tools/support/evaluation_runner.h); this file parses flags and writes the outputs.
#include <ros/package.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/evaluation/standard_table_rows.h"
#ifdef DEEP_OIS_WITH_TORCH
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#endif
#include "deep_ois/tools/support/evaluation_runner.h"
#include "deep_ois/tools/support/recorded_flows.h"

namespace {

const char* const kUsage =
    "usage: evaluate --bags FILE.bag [FILE.bag ...] [--out DIR] [--gyro-config FILE.yaml]\n"
    "                [--annotations FILE.csv [--camera ois|non-ois]] [--ghost-pairs N] "
    "[--ghost-zoom N]\n"
    "                [--max-pairs N] [--no-image-baselines] [--no-ground-truth] [--no-progress]\n"
    "                [--model FILE.pt | --no-model] [--torch-threads N] [--recorded LIVE.bag]\n";

int usage(const std::string& problem) {
  std::fprintf(stderr, "evaluate: %s\n%s", problem.c_str(), kUsage);
  return 2;
}

bool parseCount(const std::string& text, long& value) {
  char* end = nullptr;
  value = std::strtol(text.c_str(), &end, 10);
  return !text.empty() && *end == '\0' && value >= 0;
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::EvaluationOptions options;
  deep_ois::StandardMethodOptions standard;
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  std::string out_dir, annotations, camera, recorded;
  std::string model_path = package.empty() ? "" : package + "/models/fast.pt";
  int torch_threads = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    const bool has_value = i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0;
    long count = 0;
    if (flag == "--bags") {
      while (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0)
        options.bags.push_back(argv[++i]);
    } else if (flag == "--gyro-config" && has_value) {
      gyro_config = argv[++i];
    } else if (flag == "--out" && has_value) {
      out_dir = argv[++i];
    } else if (flag == "--annotations" && has_value) {
      annotations = argv[++i];
    } else if (flag == "--camera" && has_value) {
      camera = argv[++i];
    } else if ((flag == "--ghost-pairs" || flag == "--ghost-zoom" || flag == "--max-pairs") &&
               has_value) {
      if (!parseCount(argv[++i], count))
        return usage(flag + " needs a whole number >= 0, got '" + argv[i] + "'");
      if (flag == "--ghost-pairs") options.ghost_pairs_per_category = static_cast<int>(count);
      if (flag == "--ghost-zoom") options.ghost_zoom = static_cast<int>(count);
      if (flag == "--max-pairs") options.max_pairs_per_bag = static_cast<std::size_t>(count);
    } else if (flag == "--no-image-baselines") {
      standard.image_baselines = false;
    } else if (flag == "--no-ground-truth") {
      standard.ground_truth = false;
    } else if (flag == "--model" && has_value) {
      model_path = argv[++i];
    } else if (flag == "--no-model") {
      model_path.clear();
    } else if (flag == "--recorded" && has_value) {
      recorded = argv[++i];
    } else if (flag == "--torch-threads" && has_value) {
      if (!parseCount(argv[++i], count) || count < 1) return usage("--torch-threads needs a whole number >= 1");
      torch_threads = static_cast<int>(count);
    } else if (flag == "--no-progress") {
      options.show_progress = false;
    } else if (flag == "--help" || flag == "-h") {
      std::printf("%s", kUsage);
      return 0;
    } else {
      return usage("unknown flag or missing value: " + flag);
    }
  }
  if (options.bags.empty()) return usage("--bags needs at least one bag");
  if (gyro_config.empty())
    return usage("package deep_ois not found (source its setup.bash), so pass --gyro-config");
  if (!camera.empty() && annotations.empty())
    return usage("--camera applies to --annotations recordings only");
  if (camera == "ois") {
    options.annotated_scope = deep_ois::kOisCameraPairs;
  } else if (camera == "non-ois") {
    options.annotated_scope = deep_ois::kNonOisCameraPairs;
  } else if (!camera.empty()) {
    return usage("--camera is ois or non-ois, got '" + camera + "'");
  }

  deep_ois::EvaluationReport report;
  bool parity_failed = false;
#ifdef DEEP_OIS_WITH_TORCH
  std::unique_ptr<deep_ois::CompensationModel> model;
#else
  // Built without libtorch: only an explicit --model is an error, the default row is left out.
  const bool model_requested = std::find(argv + 1, argv + argc, std::string("--model")) != argv + argc;
  if (model_requested) return usage("--model: this build has no compensation network (built without libtorch)");
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
    // The shipped model: the compensation nodelet's network on the gyro flow nodelet's flow, over
    // each recording's pairs in order with the motion history, as the nodelet runs it.
#ifdef DEEP_OIS_WITH_TORCH
    if (!model_path.empty()) {
      deep_ois::setTorchThreads(torch_threads);
      model = std::make_unique<deep_ois::CompensationModel>(deep_ois::CompensationModel::load(model_path));
      auto stream = std::make_shared<deep_ois::CompensationStream>(*model);
      auto recording = std::make_shared<std::uint64_t>(0);
      runner.addMethod({"DeepOIS, shipped model (" + model->metadata().preset + ")", deep_ois::kOisCameraPairs,
                        [stream, recording](const deep_ois::FramePairContext& pair) {
                          if (pair.recording_id != *recording) stream->reset();
                          *recording = pair.recording_id;
                          return deep_ois::AlignmentEstimate::gridFlow(
                              stream->compensate(pair.gyro_flow_grid, pair.stamp_a_ns, pair.stamp_b_ns));
                        }});
    }
#else
    (void)torch_threads;
#endif
    // Replay parity: what the live nodelets published, looked up by the pair's two stamps.
    std::map<deep_ois::FramePairStamps, deep_ois::RecordedFlow> live_gyro, live_compensated;
    if (!recorded.empty()) {
      live_gyro = deep_ois::readRecordedFlows(recorded, "/deep_ois/gyro_flow");
      live_compensated = deep_ois::readRecordedFlows(recorded, "/deep_ois/compensated_flow");
      // The gyro row is scored on the recorded homographies (as the offline gyro row), the model's
      // on the recorded grid flow (as the offline model row): like with like, so they must agree.
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
                        recordedMethod(live_gyro, true)});
      runner.addMethod({"DeepOIS (live nodelets, recorded)", deep_ois::kOisCameraPairs,
                        recordedMethod(live_compensated, false)});
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
    const std::string model_row = model ? "DeepOIS, shipped model (" + model->metadata().preset + ")" : "";
#else
    const std::string model_row;
#endif
    std::vector<std::pair<std::string, std::string>> comparisons = {
        {"gyro, OIS camera (uncompensated)", "gyro, OIS camera (live nodelet, recorded)"}};
    if (model) comparisons.push_back({model_row, "DeepOIS (live nodelets, recorded)"});
    std::printf("\nreplay parity (live nodelets recorded in %s vs offline):\n", recorded.c_str());
    for (const auto& [offline, live] : comparisons) {
      const deep_ois::MethodAgreement agreement = deep_ois::compareMethods(report, offline, live);
      const bool agrees = agreement.pairs_compared > 0 && agreement.max_abs_difference_px <= kParityTolerancePx;
      std::printf("- %s: %zu pairs compared, largest difference %.6f px, %zu not in the recording: %s\n",
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
