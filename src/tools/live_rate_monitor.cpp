// live_rate_monitor: counts the messages on topics (of any type) and prints, every period, how many
// each got in that period and the resident memory (VmRSS) of a process; used by scripts/soak.sh to
// watch the live pipeline's output rate and the manager's memory, and by scripts/overload_benchmark.sh
// to count compensated flows per gyro flow.
//
//   live_rate_monitor --pid PID [--period S (60)] [--periods N (0 = until killed)] TOPIC...
//
// After the last period (with --periods) a line of totals, and each later topic's total as a
// share of the first topic's (the soak: compensated flows per gyro flow).
#include <ros/ros.h>
#include <topic_tools/shape_shifter.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/tools/support/command_line.h"

namespace {

long residentMegabytes(const std::string& pid) {
  std::ifstream status("/proc/" + pid + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::atol(line.c_str() + 6) / 1024;
  }
  return -1;  // the process is gone
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "live_rate_monitor", ros::init_options::AnonymousName);
  std::string pid;
  double period_s = 60.0;
  int periods = 0;
  std::vector<std::string> topics;
  deep_ois::ToolCommandLine command_line(
      "live_rate_monitor",
      "Counts the messages on topics (of any type) and prints, every period, how many each got in "
      "that period and the resident memory (VmRSS) of a process; scripts/soak.sh uses it to watch "
      "the live pipeline's output rate and the manager's memory, scripts/overload_benchmark.sh to "
      "count compensated flows per gyro flow.",
      "Exit status: 0 done, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--pid", pid, "the process whose memory is printed")->required()->type_name("PID");
  command_line.addNumber("--period", period_s, "seconds between two lines")
      ->check(deep_ois::greaterThan(0))
      ->type_name("SECONDS");
  command_line.addNumber("--periods", periods, "lines to print (0: until stopped)")
      ->check(deep_ois::atLeast(0));
  app.add_option("topics", topics, "topics to count (any message type)")->required()->type_name("TOPIC ...");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  ros::NodeHandle nh;
  std::vector<std::unique_ptr<std::atomic<long>>> counts;
  std::vector<ros::Subscriber> subscribers;
  for (const std::string& topic : topics) {
    counts.push_back(std::make_unique<std::atomic<long>>(0));
    std::atomic<long>* count = counts.back().get();
    // Any type: only the arrival is counted (the message is not deserialised).
    subscribers.push_back(nh.subscribe<topic_tools::ShapeShifter>(
        topic, 100, [count](const topic_tools::ShapeShifter::ConstPtr&) { ++*count; }));
  }
  ros::AsyncSpinner spinner(1);
  spinner.start();
  std::printf("%-7s %-7s", "period", "RSS_MB");
  for (const std::string& topic : topics) std::printf(" %s", topic.c_str());
  std::printf("\n");
  std::fflush(stdout);
  std::vector<long> totals(topics.size(), 0);
  for (int k = 1; ros::ok() && (periods == 0 || k <= periods); ++k) {
    ros::WallDuration(period_s).sleep();
    std::printf("%-7d %-7ld", k, residentMegabytes(pid));
    for (std::size_t t = 0; t < topics.size(); ++t) {
      const long count = counts[t]->exchange(0);
      totals[t] += count;
      std::printf(" %*ld", static_cast<int>(topics[t].size()), count);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  std::printf("%-7s %-7s", "total", "");
  for (std::size_t t = 0; t < topics.size(); ++t) std::printf(" %*ld", static_cast<int>(topics[t].size()), totals[t]);
  std::printf("\n");
  for (std::size_t t = 1; t < topics.size(); ++t) {
    std::printf("%s: %ld per %ld on %s (%.1f %%)\n", topics[t].c_str(), totals[t], totals[0], topics[0].c_str(),
                totals[0] > 0 ? 100.0 * static_cast<double>(totals[t]) / static_cast<double>(totals[0]) : 0.0);
  }
  return 0;
}
