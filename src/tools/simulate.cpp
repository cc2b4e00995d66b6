// Writes a simulated OIS (or non-OIS twin) camera sequence with exact ground truth to a rosbag.
//
//   simulate --config config/simulator/RE.yaml --seed N --duration S --out file.bag
//            [--overlay config/simulator/modules/M.yaml ...] [--ois on|off]
//            [--compression bz2|lz4|none] [--quiet]
//
// --overlay (repeatable) reads a stabiliser module or camera file over the config.
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

#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/core/sim/simulator.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

int usage(const std::string& problem) {
  std::fprintf(stderr,
               "simulate: %s\n"
               "usage: simulate --config FILE.yaml --seed N --duration SECONDS --out FILE.bag\n"
               "                [--overlay FILE.yaml ...] [--ois on|off] [--compression bz2|lz4|none] [--quiet]\n",
               problem.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_path, out_path, ois_override, compression_name = "bz2";
  std::vector<std::string> overlays;
  long seed = -1;
  double duration_s = -1.0;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--quiet") {
      quiet = true;
      continue;
    }
    if (i + 1 >= argc) return usage("flag " + flag + " needs a value");
    const std::string value = argv[++i];
    try {
      if (flag == "--config") {
        config_path = value;
      } else if (flag == "--overlay") {
        overlays.push_back(value);
      } else if (flag == "--out") {
        out_path = value;
      } else if (flag == "--seed") {
        std::size_t used = 0;
        seed = std::stol(value, &used);
        if (used != value.size() || seed < 0 || seed > 4294967295L) throw std::invalid_argument(value);
      } else if (flag == "--duration") {
        std::size_t used = 0;
        duration_s = std::stod(value, &used);
        if (used != value.size()) throw std::invalid_argument(value);
      } else if (flag == "--ois") {
        if (value != "on" && value != "off") return usage("--ois must be 'on' or 'off', got '" + value + "'");
        ois_override = value;
      } else if (flag == "--compression") {
        if (value != "bz2" && value != "lz4" && value != "none") {
          return usage("--compression must be bz2, lz4 or none, got '" + value + "'");
        }
        compression_name = value;
      } else {
        return usage("unknown flag " + flag);
      }
    } catch (const std::logic_error&) {
      return usage("flag " + flag + " needs a number, got '" + value + "'");
    }
  }
  if (config_path.empty()) return usage("--config is required");
  if (out_path.empty()) return usage("--out is required");
  if (seed < 0) return usage("--seed is required (a whole number 0..4294967295)");
  if (!(duration_s > 0.0)) return usage("--duration is required (seconds, > 0)");

  try {
    deep_ois::sim::SimulatorConfig config = deep_ois::sim::loadSimulatorConfig(config_path, overlays);
    if (!ois_override.empty()) config.ois.enabled = ois_override == "on";
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
    std::printf("simulate: %s: %s, OIS %s, seed %ld, %d frames %dx%d, %d frame pairs with %d "
                "correspondences, %d IMU samples, %d lens-shift samples, %.1f s%s\n",
                out_path.c_str(), deep_ois::sim::toString(config.category), config.ois.enabled ? "on" : "off",
                seed, stats.frames, config.sensor.width_px, config.sensor.height_px, stats.frame_pairs,
                stats.correspondences, stats.imu_messages, stats.lens_shift_messages, elapsed,
                stats.interrupted ? " (interrupted: the bag holds the frames written so far)" : "");
    return stats.interrupted ? 130 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "simulate: %s\n", e.what());
    return 1;
  }
}
