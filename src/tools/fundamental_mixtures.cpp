// Writes the Fundamental Mixtures training set of some recordings, without a roscore: one
// deep_ois/TrainingPair per consecutive frame pair (gyro homographies in, rotation-only target).
//
//   fundamental_mixtures --bags a.bag [b.bag ...] --out train.bag [--gyro-config FILE]
//       [--image-topic T] [--camera-info-topic T] [--imu-topic T] [--global]
//
// Progress on stderr, the summary on stdout. Ctrl-C (or SIGTERM) closes the output after the
// current pair, with every pair done so far; a second Ctrl-C (or SIGKILL) aborts at once: the
// output is then left unindexed, and `recover_bag` recovers every pair written (one chunk per
// pair; `rosbag reindex` all but the last). An input bag without index (cut short) is read up to
// the damage.
// Exit status: 0 all bags done, 1 nothing could be done, 2 usage, 3 some bags failed, 130 stopped.
#include <ros/package.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "deep_ois/ros/bag/fundamental_mixtures_offline.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

std::atomic<bool> g_stop{false};

// Async-signal-safe: sets the flag and restores the default action for the next signal.
void onStopSignal(int signal_number) {
  g_stop = true;
  std::signal(signal_number, SIG_DFL);
}

int usage(const std::string& problem) {
  std::fprintf(
      stderr,
      "fundamental_mixtures: %s\nusage: fundamental_mixtures --bags FILE.bag [FILE.bag ...] "
      "--out TRAIN.bag [--gyro-config config/gyro_flow.yaml] [--image-topic T] "
      "[--camera-info-topic T] [--imu-topic T] [--global]\n",
      problem.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::FundamentalMixturesOfflineOptions options;
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    const bool has_value = i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0;
    if (flag == "--bags") {
      while (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0)
        options.bags.push_back(argv[++i]);
    } else if (flag == "--out" && has_value) {
      options.output_path = argv[++i];
    } else if (flag == "--gyro-config" && has_value) {
      gyro_config = argv[++i];
    } else if (flag == "--image-topic" && has_value) {
      options.topics.image = argv[++i];
    } else if (flag == "--camera-info-topic" && has_value) {
      options.topics.camera_info = argv[++i];
    } else if (flag == "--imu-topic" && has_value) {
      options.topics.imu = argv[++i];
    } else if (flag == "--global") {
      options.global_fundamental = true;
    } else {
      return usage("unknown flag or missing value: " + flag);
    }
  }
  if (options.bags.empty()) return usage("--bags needs at least one bag");
  if (options.output_path.empty()) return usage("--out is required");
  if (gyro_config.empty())
    return usage("package deep_ois not found (source its setup.bash), so pass --gyro-config");

  try {
    options.gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
    std::unique_ptr<deep_ois::ProgressBar> bar;
    options.on_progress = [&bar](std::size_t done, std::size_t total) {
      if (!bar) bar = std::make_unique<deep_ois::ProgressBar>(total, "pairs");
      bar->update(done);
    };
    const deep_ois::FundamentalMixturesOffline job(options);
    std::signal(SIGINT, onStopSignal);
    std::signal(SIGTERM, onStopSignal);
    const deep_ois::FundamentalMixturesSummary summary = job.run(&g_stop);
    std::fprintf(stderr, "\n");
    std::printf("fundamental_mixtures: %s: %s", options.output_path.c_str(),
                summary.text().c_str());
    if (summary.interrupted) return 130;
    if (summary.pairs_done == 0) return 1;
    return summary.bag_errors.empty() ? 0 : 3;
  } catch (const std::invalid_argument& e) {
    return usage(e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fundamental_mixtures: %s\n", e.what());
    return 1;
  }
}
