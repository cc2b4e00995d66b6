// Benchmarks the fused motion (core/fusion/fused_motion.h) on simulator recordings: the evaluator's
// table (tools/support/evaluation_runner.h, the paper's geometry distance, capped at identity and
// uncapped) with the gyro rows, the stabiliser model's compensation (the prior) and the fused motion
// beside it, then per category the share of pairs the tracks refined, their mean correction, why
// the others kept the prior, and the cost of the tracking and of the fusion per pair.
//
// The fused row runs its own copy of the stabiliser row (the same model, its state carried over
// each recording), tracks every pair with the online learner's tracker (its corners and KLT, on the
// full frame) and fuses. The prior's uncertainty is the median of the compensation's per-pair check
// (compensation_check.h: the model's residual on the tracks) over the recording's last pairs, as
// the live pipeline would know it: the pair's own check is added after its fusion.
// Flags: `benchmark_fusion --help`; what it prints: docs/fusion.md.
#include <ros/package.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/evaluation/stabiliser_table_row.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/core/fusion/fused_motion.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/online/compensation_check.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/evaluation_runner.h"

namespace {

constexpr const char* kDescription =
    "Scores the fused motion (the stabiliser model's compensation refined by the pair's tracks) "
    "beside the compensation alone and the gyro rows on simulator recordings (e.g. "
    "scripts/make_datasets.sh's evaluation split): the paper's table, capped and uncapped, then per "
    "category the pairs refined, the mean correction, why the others kept the prior, and the cost "
    "of tracking and fusing. Manual: docs/fusion.md.";

// How the fused row is run.
struct FusedRowSettings {
  deep_ois::FusionOptions fusion;
  deep_ois::CompensationCheckOptions check;
  std::size_t recent_checks = 10;  // the prior's sigma: median of the last checks' model residuals
  double initial_sigma_px = 0.5;   // before the recording's first usable check
  double min_sigma_px = 0.1;       // the checks' residual holds the tracks' noise; never below this
  double fixed_sigma_px = 0.0;     // > 0: this sigma on every pair instead of the checks'
};

// What the fused row did, per category.
struct FusionTally {
  struct Category {
    std::size_t pairs = 0, refined = 0;
    double correction_sum_px = 0.0, given_sigma_sum_px = 0.0, used_sigma_sum_px = 0.0;
    std::map<std::string, std::size_t> kept;  // the reason's first words -> pairs
  };
  std::map<std::string, Category> categories;
  double tracking_s = 0.0, fusion_s = 0.0, check_s = 0.0;
  std::size_t pairs = 0;
};

// The kind of reason a pair kept the prior: its text up to the first digit or colon after
// "prior kept: " ("no tracks", "inconsistent tracks", "tracks consistent with the prior", ...).
std::string reasonKind(const std::string& reason) {
  std::string kind = reason.substr(std::string("prior kept: ").size());
  if (kind.rfind("inconsistent", 0) == 0) return "inconsistent tracks";
  if (kind.find("consistent with the prior") != std::string::npos) return "too few consistent tracks";
  if (kind.find("fit within") != std::string::npos) return "too few tracks fit";
  if (kind.find("do not improve") != std::string::npos) return "no improvement";
  return kind;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

deep_ois::AlignmentMethod fusedMethod(const std::string& name, deep_ois::AlignmentMethod prior_row,
                                      const FusedRowSettings& settings, std::shared_ptr<FusionTally> tally) {
  struct State {
    deep_ois::FeatureTracker tracker{deep_ois::OnlineLearningOptions::learningCorners(),
                                     deep_ois::OnlineLearningOptions::learningKlt()};
    std::uint64_t recording = std::numeric_limits<std::uint64_t>::max();
    std::deque<double> recent_residuals_px;
  };
  auto state = std::make_shared<State>();
  return {name, prior_row.scope, [=](const deep_ois::FramePairContext& pair) {
            const deep_ois::AlignmentEstimate prior = prior_row.estimate(pair);
            if (!prior.ok()) return prior;
            if (pair.recording_id != state->recording) {
              state->recording = pair.recording_id;
              state->recent_residuals_px.clear();
            }
            double sigma_px = settings.fixed_sigma_px;
            if (!(sigma_px > 0.0)) {
              const std::vector<double> recent(state->recent_residuals_px.begin(), state->recent_residuals_px.end());
              sigma_px = recent.empty() ? settings.initial_sigma_px
                                        : std::max(settings.min_sigma_px, deep_ois::median(recent));
            }
            auto start = std::chrono::steady_clock::now();
            const std::vector<deep_ois::FeatureMatch> matches = state->tracker.match(pair.gray_a, pair.gray_b);
            tally->tracking_s += secondsSince(start);
            start = std::chrono::steady_clock::now();
            const deep_ois::FusedMotion fused =
                deep_ois::fuseMotion(*pair.camera, {prior.homographies, sigma_px}, matches, settings.fusion);
            tally->fusion_s += secondsSince(start);
            start = std::chrono::steady_clock::now();
            const deep_ois::CompensationCheck check = deep_ois::checkCompensation(
                *pair.camera, matches, prior.homographies, pair.gyro_homographies, settings.check);
            tally->check_s += secondsSince(start);
            if (check.usable) {
              state->recent_residuals_px.push_back(check.model_residual_px);
              if (state->recent_residuals_px.size() > settings.recent_checks) state->recent_residuals_px.pop_front();
            }
            FusionTally::Category& category = tally->categories[pair.category];
            ++category.pairs;
            ++tally->pairs;
            category.given_sigma_sum_px += sigma_px;
            category.used_sigma_sum_px += fused.sigma_px;
            if (fused.refined) {
              ++category.refined;
              category.correction_sum_px += fused.mean_correction_px;
            } else {
              ++category.kept[reasonKind(fused.reason)];
            }
            return deep_ois::AlignmentEstimate::patchHomographies(fused.homographies);
          }};
}

void printTally(const FusionTally& tally) {
  std::printf("\nfusion per category (the fused row's pairs):\n\n");
  std::printf("| category | pairs | refined | mean correction of the refined, px | prior sigma given / used, px | prior kept because |\n");
  std::printf("| --- | ---: | ---: | ---: | ---: | --- |\n");
  for (const auto& [name, c] : tally.categories) {
    std::string kept;
    for (const auto& [reason, count] : c.kept) kept += (kept.empty() ? "" : "; ") + reason + " " + std::to_string(count);
    const double pairs = std::max<double>(1.0, c.pairs);
    std::printf("| %s | %zu | %.1f %% | %.3f | %.3f / %.3f | %s |\n", name.c_str(), c.pairs, 100.0 * c.refined / pairs,
                c.refined ? c.correction_sum_px / c.refined : 0.0, c.given_sigma_sum_px / pairs,
                c.used_sigma_sum_px / pairs, kept.empty() ? "-" : kept.c_str());
  }
  if (tally.pairs > 0) {
    std::printf("\ncost per pair (wall, one thread): tracking %.2f ms, fusion %.2f ms, per-pair check %.2f ms\n",
                1e3 * tally.tracking_s / tally.pairs, 1e3 * tally.fusion_s / tally.pairs,
                1e3 * tally.check_s / tally.pairs);
  }
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::EvaluationOptions options;
  FusedRowSettings settings;
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
  const std::string problem = settings.fusion.validate();
  if (!problem.empty()) return command_line.usageError(problem);
  options.show_progress = !no_progress;
  options.ghost_pairs_per_category = 0;

  auto tally = std::make_shared<FusionTally>();
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
    runner.addMethod(fusedMethod(fused_row,
                                 deep_ois::stabiliserAlignmentMethod("prior of the fused row", model.parameters),
                                 settings, tally));
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
  printTally(*tally);
  const auto fused_s = report.method_s.find(fused_row);
  std::printf("\n%.1f s in all; the fused row %.1f s (its prior, tracking, fusion and check)\n", report.elapsed_s,
              fused_s == report.method_s.end() ? 0.0 : fused_s->second);
  return report.complete() ? 0 : 3;
}
