// Benchmarks the stabiliser model on generated stabiliser designs at the level of the lens: per
// design, train_stabiliser's fit and candidate choice (the physical chain, its variants and the
// compositions with the linear-dynamics stage) on 6 training traces, the choice on a 7th, then
// the lens-motion error on 2 evaluation traces, beside no lens motion (the plain gyro) and the
// design's own controller on the camera's gyro (the oracle). No image is rendered: the lens motions
// are the simulator's truth plus the images' measurement noise, so it runs over many designs in
// minutes (flags: `benchmark_lens_dynamics --help`, docs/stabiliser_model.md).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/design_traces.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/design_trace_recording.h"

namespace {

using deep_ois::CameraRateSample;
using deep_ois::StabiliserFitRecording;
namespace sim = deep_ois::sim;

struct Settings {
  double focal_px = 257.0;  // the RE camera
  double frame_rate_hz = 30.0;
  double readout_s = 0.022;
  int patches = 8;
  double duration_s = 5.0;
  double noise_px = 0.1;  // the images' lens-motion noise (the tracker's, gyro-anchored)
};

double rmsAgainst(const std::vector<StabiliserFitRecording>& truth,
                  const std::vector<std::vector<Eigen::Vector2d>>& predicted) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t r = 0; r < truth.size(); ++r)
    for (std::size_t i = 0; i < truth[r].observations.size(); ++i) {
      if (!predicted[r][i].allFinite()) continue;
      sum += (predicted[r][i] - truth[r].observations[i].motion_px).squaredNorm();
      ++count;
    }
  return count ? std::sqrt(sum / static_cast<double>(count)) : std::nan("");
}

}  // namespace

constexpr char kDescription[] =
    "Benchmarks the stabiliser model on generated stabiliser designs at the level of the lens (no "
    "image rendered): per design, the fit and candidate choice of train_stabiliser on 6 training "
    "traces of 5 s and a 7th for the choice, then the lens-motion RMS on 2 evaluation traces, "
    "beside no lens motion (the plain gyro) and the design's own controller on the camera's gyro "
    "(the oracle). 'Closed' is 1 - RMS / RMS without a lens model, the share of the lens motion "
    "explained (the images' gap to the non-OIS twin follows it, less the tracker's floor). Prints a "
    "row per design and a summary per class; --csv writes the rows.";

int main(int argc, char** argv) {
  std::string split = "held_out", csv_path;
  std::uint32_t seed_begin = 0, count = 40;
  Settings settings;
  bool chain_candidates = true, describe = false, list_candidates = false, oracle_cost = false;
  deep_ois::ToolCommandLine command_line("benchmark_lens_dynamics", kDescription);
  CLI::App& app = command_line.app();
  app.add_option("--split", split, "which designs: the generator's held-out seeds (seed % 5 == 0) "
                                   "or its training split")
      ->check(deep_ois::oneOf({"held_out", "training"}))
      ->capture_default_str();
  command_line.addNumber("--seed-begin", seed_begin, "first design seed considered");
  command_line.addNumber("--count", count, "designs of the split from --seed-begin on");
  command_line.addNumber("--noise", settings.noise_px, "lens-motion measurement noise, px (per axis)");
  app.add_option("--chain-candidates", chain_candidates,
                 "also fit the chain's structural candidates (slower)")
      ->capture_default_str();
  std::vector<std::string> classes;
  app.add_option("--classes", classes, "only designs of these classes, comma-separated (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(sim::designClasses()));
  app.add_flag("--describe", describe, "print each design's description under its row");
  app.add_flag("--candidates", list_candidates,
               "print every candidate under its row: its lens-motion RMS on the choice trace and "
               "the share it explains on the evaluation traces");
  app.add_flag("--oracle-cost", oracle_cost,
               "print, under each row, the fit's own cost (Huber, per lens motion) and RMS on the "
               "training traces and the RMS on the choice trace, of the design's own model (the "
               "oracle, designModel) beside the kept candidate's and the one with the lowest "
               "training RMS: an oracle well below them says the data single it out and the "
               "candidates cannot reach it (their structure or their start); a candidate at or "
               "below it with a worse evaluation is an over-fit");
  app.add_option("--csv", csv_path, "write the rows here")->type_name("FILE.csv");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    std::ofstream csv;
    if (!csv_path.empty()) {
      csv.open(csv_path);
      if (!csv) throw std::runtime_error("cannot write " + csv_path);
      csv << "design_seed,class,none_px,kept_px,kept,oracle_px,closed_kept,closed_oracle,seconds\n";
    }
    const sim::DesignSplit wanted = split == "held_out" ? sim::DesignSplit::kHeldOut : sim::DesignSplit::kTraining;
    sim::DesignTraceOptions trace_options;
    trace_options.duration_s = settings.duration_s;
    trace_options.focal_px = settings.focal_px;
    const deep_ois::DesignTraceCamera camera{settings.focal_px, settings.frame_rate_hz, settings.readout_s,
                                             settings.patches};
    deep_ois::StabiliserFitOptions fit_options;
    fit_options.check_timing = false;
    deep_ois::StabiliserCandidateKinds kinds;
    kinds.structural = chain_candidates;
    std::printf("%-6s %-12s %8s %8s %8s %7s %7s %s\n", "design", "class", "none px", "kept px", "oracle",
                "kept %", "oracle %", "kept");
    std::map<std::string, std::vector<double>> kept_by_class, oracle_by_class;
    std::vector<double> kept_all, oracle_all, gap_to_oracle;
    int meets = 0, designs = 0;
    for (std::uint32_t seed = seed_begin; designs < static_cast<int>(count); ++seed) {
      if (sim::designSplit(seed) != wanted) continue;
      const auto started = std::chrono::steady_clock::now();
      const sim::StabiliserDesign design = sim::generateDesign(seed);
      if (!classes.empty() && std::find(classes.begin(), classes.end(), sim::designClass(design)) == classes.end())
        continue;
      ++designs;
      std::vector<StabiliserFitRecording> training, choice, evaluation, oracle;
      for (std::uint32_t m = 101; m <= 109; ++m) {
        const sim::DesignTrace trace = sim::simulateDesignTrace(seed, m, trace_options);
        if (m <= 107) {
          (m <= 106 ? training : choice).push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, settings.noise_px, m));
        } else {
          evaluation.push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, 0.0, m));
          oracle.push_back(deep_ois::designTraceRecording(trace, sim::designLensShifts(design, settings.focal_px, trace.gyro),
                                                camera, 0.0, m));
        }
      }
      const deep_ois::StabiliserFitResult fit = deep_ois::fitStabiliser(training, fit_options);
      const deep_ois::StabiliserSelection selection =
          deep_ois::selectStabiliser(fit, training, choice, fit_options, {}, kinds);
      std::vector<std::vector<Eigen::Vector2d>> oracle_motion;
      for (const auto& r : oracle) {
        std::vector<Eigen::Vector2d> m;
        for (const auto& o : r.observations) m.push_back(o.motion_px);
        oracle_motion.push_back(m);
      }
      auto rmsOf = [&](const deep_ois::StabiliserModel& p) {
        return deep_ois::scoreStabiliser(p, evaluation, fit_options).rms_px;
      };
      const double none = rmsOf(deep_ois::noLensMotion());
      const double kept = rmsOf(selection.candidates[selection.kept].parameters);
      const double oracle_rms = rmsAgainst(evaluation, oracle_motion);
      auto closed = [&](double v) { return 100.0 * (1.0 - v / none); };
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      const std::string cls = sim::designClass(design);
      std::printf("%-6u %-12s %8.4f %8.4f %8.4f %6.1f%% %6.1f%% %s (%.0f s)\n", seed, cls.c_str(), none, kept,
                  oracle_rms, closed(kept), closed(oracle_rms), selection.candidates[selection.kept].name.c_str(),
                  seconds);
      if (list_candidates)
        for (const auto& c : selection.candidates)
          std::printf("       %s %-70s choice %.4f px, evaluation %.1f%%\n", &c == &selection.candidates[selection.kept] ? "*" : " ",
                      c.name.c_str(), c.held_out.rms_px, closed(rmsOf(c.parameters)));
      if (oracle_cost) {
        // The design's own model runs at its physics step (designModel); the candidates at the fit's.
        deep_ois::StabiliserFitOptions oracle_options = fit_options;
        oracle_options.step_s = 1.0 / sim::kDesignPhysicsRateHz;
        const deep_ois::StabiliserModel own = sim::designModel(design);
        auto perMotion = [](double cost, const deep_ois::StabiliserScore& score) {
          return score.observations ? cost / static_cast<double>(score.observations) : std::nan("");
        };
        auto line = [&](const char* what, const deep_ois::StabiliserModel& m,
                        const deep_ois::StabiliserFitOptions& o) {
          const deep_ois::StabiliserScore train = deep_ois::scoreStabiliser(m, training, o);
          std::printf("       %-9s training cost %.5f per motion, RMS %.4f px; choice RMS %.4f px; evaluation %.1f%%\n",
                      what, perMotion(deep_ois::stabiliserFitCost(m, training, o), train), train.rms_px,
                      deep_ois::scoreStabiliser(m, choice, o).rms_px,
                      closed(deep_ois::scoreStabiliser(m, evaluation, o).rms_px));
        };
        line("oracle", own, oracle_options);
        line("kept", selection.candidates[selection.kept].parameters, fit_options);
        std::size_t lowest = 0;
        for (std::size_t k = 1; k < selection.candidates.size(); ++k)
          if (selection.candidates[k].training.rms_px < selection.candidates[lowest].training.rms_px) lowest = k;
        line("lowest", selection.candidates[lowest].parameters, fit_options);
        std::printf("       (lowest training RMS: %s)\n", selection.candidates[lowest].name.c_str());
      }
      if (describe) {
        std::string tags;
        for (const std::string& tag : sim::designFeatures(design)) tags += " " + tag;
        std::printf("       features:%s\n       %s\n", tags.c_str(), sim::describe(design).c_str());
      }
      std::fflush(stdout);
      kept_by_class[cls].push_back(closed(kept));
      oracle_by_class[cls].push_back(closed(oracle_rms));
      kept_all.push_back(closed(kept));
      oracle_all.push_back(closed(oracle_rms));
      gap_to_oracle.push_back(closed(oracle_rms) - closed(kept));
      if (closed(kept) >= 95.0 || closed(kept) >= closed(oracle_rms) - 3.0) ++meets;
      if (csv)
        csv << seed << "," << cls << "," << none << "," << kept << ",\"" << selection.candidates[selection.kept].name
            << "\"," << oracle_rms << "," << closed(kept) << "," << closed(oracle_rms) << "," << seconds << "\n";
    }
    std::printf("\nper class (median closed: kept / oracle):\n");
    for (const auto& [cls, values] : kept_by_class)
      std::printf("  %-12s %2zu designs  %6.1f %% / %6.1f %%\n", cls.c_str(), values.size(), deep_ois::median(values),
                  deep_ois::median(oracle_by_class[cls]));
    std::printf("all %d designs (%s split): median closed %.1f %% (oracle %.1f %%), median distance to "
                "the oracle %.1f points; %d of %d (%.0f %%) reach 95 %% or within 3 points of the oracle\n",
                designs, split.c_str(), deep_ois::median(kept_all), deep_ois::median(oracle_all), deep_ois::median(gap_to_oracle), meets,
                designs, 100.0 * meets / std::max(1, designs));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_lens_dynamics: %s\n", e.what());
    return 1;
  }
  return 0;
}
