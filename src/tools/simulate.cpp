// Writes a simulated OIS (or non-OIS twin) camera sequence with exact ground truth to a rosbag.
// Flags: --help.
//
// Same config and seed -> identical bag content. Ctrl-C closes the bag after the current frame.
#include <rosbag/bag.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/simulator.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

}  // namespace

constexpr char kDescription[] =
    "Writes a simulated OIS (or non-OIS twin) camera sequence with exact ground truth to a rosbag: "
    "the camera, IMU, tf and camera_info topics a real robot would record, plus ground-truth "
    "topics "
    "(true per-row motion, OIS lens shift, annotated point correspondences, category). Same config "
    "and seed -> identical bag content. Ctrl-C closes the bag after the current frame.";

int main(int argc, char** argv) {
  std::string config_path, out_path, ois_override, compression_name = "bz2";
  std::vector<std::string> overlays;
  std::uint32_t seed = 0;
  double duration_s = 0.0;
  bool quiet = false;
  deep_ois::ToolCommandLine command_line("simulate", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage, 130 stopped.");
  CLI::App& app = command_line.app();
  app.add_option("--config", config_path, "simulator config, e.g. config/simulator/RE.yaml")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  command_line.addNumber("--seed", seed, "the simulator's seed, 0..4294967295")
      ->required()
      ->default_str("");
  command_line.addNumber("--duration", duration_s, "length of the sequence, seconds (> 0)")
      ->required()
      ->default_str("")
      ->check(deep_ois::greaterThan(0))
      ->type_name("SECONDS");
  app.add_option("--overlay", overlays,
                 "stabiliser module or camera files read over the config, in order, e.g. "
                 "config/simulator/modules/pan_release.yaml (repeatable)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--out", out_path, "the bag to write")->required()->type_name("FILE.bag");
  std::uint32_t design_seed = 0;
  CLI::Option* design_option =
      command_line
          .addNumber("--design-seed", design_seed,
                     "run the lens by the generated stabiliser design of this seed, "
                     "0..4294967295, instead of the config's stabiliser (as ois.design_seed; "
                     "docs/simulator.md)")
          ->default_str("")
          ->type_name("SEED");
  app.add_option("--ois", ois_override, "override the config's OIS (off: the non-OIS twin)")
      ->check(deep_ois::oneOf({"on", "off"}))
      ->type_name("on|off");
  app.add_option("--compression", compression_name, "bag compression")
      ->check(deep_ois::oneOf({"bz2", "lz4", "none"}))
      ->capture_default_str()
      ->type_name("bz2|lz4|none");
  app.add_flag("--quiet", quiet, "no progress bar");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    deep_ois::sim::SimulatorConfig config = deep_ois::sim::loadSimulatorConfig(config_path, overlays);
    if (!ois_override.empty()) config.ois.enabled = ois_override == "on";
    if (design_option->count() > 0) config.ois.design_seed = design_seed;
    std::string design;
    if (config.ois.design_seed >= 0) {
      const auto seed = static_cast<std::uint32_t>(config.ois.design_seed);
      design = std::string(", generated design ") + std::to_string(seed) + " (" +
               deep_ois::sim::designClass(deep_ois::sim::generateDesign(seed)) + ", " +
               deep_ois::sim::toString(deep_ois::sim::designSplit(seed)) + ")";
    }
    const auto started = std::chrono::steady_clock::now();
    const deep_ois::sim::Simulator simulator(config, static_cast<std::uint32_t>(seed), duration_s);

    const auto compression = compression_name == "bz2"   ? rosbag::compression::BZ2
                             : compression_name == "lz4" ? rosbag::compression::LZ4
                                                         : rosbag::compression::Uncompressed;
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    deep_ois::ProgressBar bar(static_cast<std::size_t>(simulator.frameCount()), "frames");
    auto progress = [&](int done, int) {
      if (!quiet) bar.update(static_cast<std::size_t>(done));
    };
    const deep_ois::SimulationBagStats stats = deep_ois::writeSimulationBag(
        simulator, out_path, compression, deep_ois::SimulationBagTopics{}, progress, &g_stop);
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    std::printf(
        "simulate: %s: %s, OIS %s%s, seed %u, %d frames %dx%d, %d frame pairs with %d "
        "correspondences, %d IMU samples, %d lens-shift samples (truth), %d logged by the camera, %.1f s%s\n",
        out_path.c_str(), deep_ois::sim::toString(config.category),
        config.ois.enabled ? "on" : "off", design.c_str(), seed, stats.frames, config.sensor.width_px,
        config.sensor.height_px, stats.frame_pairs, stats.correspondences, stats.imu_messages,
        stats.lens_shift_messages, stats.lens_shift_log_messages, elapsed,
        stats.interrupted ? " (interrupted: the bag holds the frames written so far)" : "");
    return stats.interrupted ? 130 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "simulate: %s\n", e.what());
    return 1;
  }
}
