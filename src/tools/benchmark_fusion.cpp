// Benchmarks the fused motion (core/fusion/fused_motion.h) on simulator recordings: the evaluator's
// table (tools/support/evaluation_runner.h, the paper's geometry distance, capped at identity and
// uncapped) with the gyro rows, the stabiliser model's compensation (the prior) and the fused motion
// beside it, then per category the share of pairs the tracks refined, their mean correction, why
// the others kept the prior, and the cost of the tracking and of the fusion per pair.
//
// The fused row is evaluate's (core/evaluation/fused_table_row.h) over its own copy of the
// stabiliser row (the same model, its state carried over each recording); here with its tuning
// flags and the per-category tally.
// Flags: `benchmark_fusion --help`; what it prints: docs/fusion.md.
#include <ros/package.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "deep_ois/core/evaluation/fused_table_row.h"
#include "deep_ois/core/evaluation/stabiliser_table_row.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/evaluation_runner.h"

namespace {

constexpr const char* kDescription =
    "Scores the fused motion (the stabiliser model's compensation refined by the pair's tracks) "
    "beside the compensation alone and the gyro rows on simulator recordings (e.g. "
    "scripts/make_datasets.sh's evaluation split): the paper's table, capped and uncapped, then per "
    "category the pairs refined, the mean correction, why the others kept the prior, and the cost "
    "of tracking and fusing. Manual: docs/fusion.md.";

}  // namespace

int main(int argc, char** argv) {
  deep_ois::EvaluationOptions options;
  deep_ois::FusedRowOptions settings;
  std::string stabiliser_path, gyro_config;
  bool no_progress = false;
  const std::string package = ros::package::getPath("deep_ois");
  if (!package.empty()) {
    stabiliser_path = package + "/models/stabiliser_generic.yaml";
    gyro_config = package + "/config/gyro_flow.yaml";
  }
  deep_ois::ToolCommandLine command_line("benchmark_fusion", kDescription);
  CLI::App& app = command_line.app();
  app.add_option("--bags", options.bags, "simulator recordings (OIS on, with their non-OIS twins for the twin row)")
      ->required()
      ->check(deep_ois::existingFile());
  app.add_option("--stabiliser", stabiliser_path, "the stabiliser model whose compensation is the prior")
      ->capture_default_str();
  app.add_option("--gyro-config", gyro_config, "the gyro flow nodelet's parameters")->capture_default_str();
  command_line.addNumber("--max-pairs", options.max_pairs_per_bag, "score only the first pairs of each bag (0: all)");
  command_line.addNumber("--prior-sigma", settings.fixed_sigma_px,
                         "the prior's sigma on every pair, px (0: the median of the recent per-pair checks)");
  command_line.addNumber("--consistency-sigmas", settings.fusion.consistency_sigmas,
                         "tracks beyond this many sigmas of the prior are left out");
  command_line.addNumber("--smoothness", settings.fusion.smoothness_px,
                         "1-sigma change of the correction between neighbouring patches, px");
  command_line.addNumber("--min-tracks", settings.fusion.min_tracks, "fewer consistent tracks: the prior is kept");
  app.add_flag("--no-progress", no_progress, "no progress bar");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (stabiliser_path.empty() || gyro_config.empty()) {
    return command_line.usageError("package deep_ois not found (source its setup.bash), so pass --stabiliser and --gyro-config");
  }
  const std::string problem = settings.validate();
  if (!problem.empty()) return command_line.usageError(problem);
  options.show_progress = !no_progress;
  options.ghost_pairs_per_category = 0;

  auto tally = std::make_shared<deep_ois::FusionTally>();
  const std::string file = std::filesystem::path(stabiliser_path).filename().string();
  const std::string fused_row = "fused: stabiliser model, " + file + " + tracks";
  deep_ois::EvaluationReport report;
  try {
    options.gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
    const deep_ois::StabiliserModelFile model = deep_ois::StabiliserModelFile::load(stabiliser_path);
    deep_ois::EvaluationRunner runner(options);
    runner.addMethod(deep_ois::identityMethod());
    runner.addMethods(deep_ois::gyroMethods());
    runner.addMethod(deep_ois::stabiliserAlignmentMethod("stabiliser model, " + file, model.parameters));
    runner.addMethod(deep_ois::fusedAlignmentMethod(
        fused_row, deep_ois::stabiliserAlignmentMethod("prior of the fused row", model.parameters), settings, tally));
    report = runner.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_fusion: %s\n", e.what());
    return 1;
  }
  for (const deep_ois::RecordingOutcome& recording : report.recordings) {
    if (!recording.error.empty()) std::fprintf(stderr, "benchmark_fusion: %s (not scored)\n", recording.error.c_str());
  }
  if (report.table.methods().empty()) {
    std::fprintf(stderr, "benchmark_fusion: no frame pair could be scored\n");
    return 1;
  }
  std::printf("%s", report.markdown().c_str());
  std::printf("\nfusion per category (the fused row's pairs):\n\n%s", tally->markdown().c_str());
  const auto fused_s = report.method_s.find(fused_row);
  std::printf("\n%.1f s in all; the fused row %.1f s (its prior, tracking, fusion and check)\n", report.elapsed_s,
              fused_s == report.method_s.end() ? 0.0 : fused_s->second);
  return report.complete() ? 0 : 3;
}
