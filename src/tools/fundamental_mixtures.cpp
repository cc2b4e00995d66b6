// Writes the Fundamental Mixtures training set of some recordings, without a roscore: one
// deep_ois/TrainingPair per consecutive frame pair (gyro homographies in, rotation-only target).
// Flags: --help.
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
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

std::atomic<bool> g_stop{false};

// Async-signal-safe: sets the flag and restores the default action for the next signal.
void onStopSignal(int signal_number) {
  g_stop = true;
  std::signal(signal_number, SIG_DFL);
}

}  // namespace

constexpr char kDescription[] =
    "Writes the Fundamental Mixtures training set of some recordings, without a roscore: one "
    "deep_ois/TrainingPair per consecutive frame pair (gyro homographies in, rotation-only "
    "target). "
    "Progress on stderr, the summary on stdout. Ctrl-C (or SIGTERM) closes the output after the "
    "current pair, with every pair done so far; a second Ctrl-C aborts at once (the output is then "
    "left unindexed: `rosbag reindex` recovers it).";

int main(int argc, char** argv) {
  deep_ois::FundamentalMixturesOfflineOptions options;
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  deep_ois::ToolCommandLine command_line("fundamental_mixtures", kDescription,
                                         "Exit status: 0 all bags done, 1 nothing could be done, 2 "
                                         "usage, 3 some bags failed, 130 stopped.");
  CLI::App& app = command_line.app();
  app.add_option("--bags", options.bags, "the recordings")->required()->type_name("FILE.bag");
  app.add_option("--out", options.output_path, "the training set to write")
      ->required()
      ->type_name("TRAIN.bag");
  app.add_option(
         "--gyro-config", gyro_config,
         "the gyro flow nodelet's parameters (default: the package's config/gyro_flow.yaml)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--image-topic", options.topics.image, "image topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--camera-info-topic", options.topics.camera_info, "camera_info topic")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--imu-topic", options.topics.imu, "IMU topic (sensor_msgs/Imu)")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_flag("--global", options.global_fundamental,
               "one global fundamental matrix instead of the mixture");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (gyro_config.empty()) {
    return command_line.usageError(
        "package deep_ois not found (source its setup.bash), so pass --gyro-config");
  }

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
    return command_line.usageError(e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fundamental_mixtures: %s\n", e.what());
    return 1;
  }
}
