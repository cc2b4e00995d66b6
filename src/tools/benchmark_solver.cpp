// Benchmarks the engines of the package's nonlinear least-squares solver
// (core/common/nonlinear_least_squares.h: its own Levenberg-Marquardt, Ceres and Eigen's MINPACK
// port) on the stabiliser fit: per generated design, the same training traces and the same start,
// fitStabiliser with each engine, then the final Huber cost on the training traces, the lens-motion
// RMS on held-back evaluation traces, the accepted steps and the process CPU time, and each
// engine's CPU over all designs as a ratio to the default engine's (flags: `benchmark_solver
// --help`, docs/solver.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/design_traces.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/design_trace_recording.h"

namespace {

using deep_ois::StabiliserFitRecording;
namespace sim = deep_ois::sim;

double cpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

}  // namespace

constexpr char kDescription[] =
    "Benchmarks the solver's three engines (the package's Levenberg-Marquardt, Ceres, Eigen's "
    "MINPACK) on the stabiliser fit: per generated design, fitStabiliser with each engine on the same "
    "training traces from the same start (no timing check), then the final Huber "
    "cost on the training traces, the lens-motion RMS on 2 evaluation traces, the accepted steps and "
    "the CPU seconds; each engine's CPU over all designs as a ratio to the first engine's. Decide on "
    "the training split; the held-out split is for reporting apart.";

int main(int argc, char** argv) {
  std::string split = "training";
  std::uint32_t seed_begin = 0, count = 4, traces = 3;
  double noise_px = 0.1;
  deep_ois::ToolCommandLine command_line("benchmark_solver", kDescription);
  CLI::App& app = command_line.app();
  app.add_option("--split", split, "which designs: the generator's training split or its held-out seeds")
      ->check(deep_ois::oneOf({"training", "held_out"}))
      ->capture_default_str();
  command_line.addNumber("--seed-begin", seed_begin, "first design seed considered");
  command_line.addNumber("--count", count, "designs of the split from --seed-begin on");
  command_line.addNumber("--traces", traces, "training traces of 5 s per design");
  command_line.addNumber("--noise", noise_px, "lens-motion measurement noise, px (per axis)");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    const sim::DesignSplit wanted = split == "held_out" ? sim::DesignSplit::kHeldOut : sim::DesignSplit::kTraining;
    sim::DesignTraceOptions trace_options;
    trace_options.duration_s = 5.0;
    const deep_ois::DesignTraceCamera camera;  // the standard split's RE camera
    trace_options.focal_px = camera.focal_px;
    deep_ois::StabiliserFitOptions options;
    options.check_timing = false;
    const deep_ois::SolverEngine engines[] = {deep_ois::SolverEngine::kLevenbergMarquardt,
                                              deep_ois::SolverEngine::kCeres,
                                              deep_ois::SolverEngine::kEigenLevenbergMarquardt};
    constexpr int kEngines = 3;
    const char* columns[kEngines] = {"lm", "ceres", "eigen"};
    std::printf("%-6s %-20s", "design", "class");
    for (const char* column : columns) std::printf(" | %-5s %10s %8s %5s %6s", column, "cost", "eval px", "steps", "cpu s");
    std::printf("\n");
    double cpu_total[kEngines] = {}, cost_total[kEngines] = {};
    int designs = 0, lowest_cost[kEngines] = {};
    for (std::uint32_t seed = seed_begin; designs < static_cast<int>(count); ++seed) {
      if (sim::designSplit(seed) != wanted) continue;
      ++designs;
      std::vector<StabiliserFitRecording> training, evaluation;
      for (std::uint32_t m = 101; m < 101 + traces + 2; ++m) {
        const sim::DesignTrace trace = sim::simulateDesignTrace(seed, m, trace_options);
        if (m < 101 + traces) training.push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, noise_px, m));
        else evaluation.push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, 0.0, m));
      }
      std::printf("%-6u %-20s", seed, sim::designClass(sim::generateDesign(seed)));
      double cost[kEngines];
      for (int e = 0; e < kEngines; ++e) {
        options.solver_engine = engines[e];
        const double started = cpuSeconds();
        const deep_ois::StabiliserFitResult fit = deep_ois::fitStabiliser(training, options);
        const double cpu = cpuSeconds() - started;
        cost[e] = deep_ois::stabiliserFitCost(fit.parameters, training, options);
        const double eval_px = deep_ois::scoreStabiliser(fit.parameters, evaluation, options).rms_px;
        std::printf(" | %-5s %10.4f %8.4f %5zu %6.2f", "", cost[e], eval_px, fit.rms_history.size(), cpu);
        cpu_total[e] += cpu;
        cost_total[e] += cost[e];
      }
      ++lowest_cost[std::min_element(cost, cost + kEngines) - cost];
      std::printf("\n");
      std::fflush(stdout);
    }
    std::printf("\n%d designs (%s split):\n", designs, split.c_str());
    for (int e = 0; e < kEngines; ++e) {
      std::printf("  %-20s CPU %6.1f s (ratio to %s %.2f), summed final cost %.4f, lowest cost on %d\n",
                  deep_ois::solverEngineName(engines[e]), cpu_total[e], deep_ois::solverEngineName(engines[0]),
                  cpu_total[e] / std::max(1e-9, cpu_total[0]), cost_total[e], lowest_cost[e]);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_solver: %s\n", e.what());
    return 1;
  }
  return 0;
}
