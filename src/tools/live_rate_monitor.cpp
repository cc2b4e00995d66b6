// live_rate_monitor: counts the messages on image topics (sensor_msgs/Image) and prints, every
// period, how many each got in that period and the resident memory (VmRSS) of a process; used by
// scripts/soak.sh to watch the live pipeline's output rate and the manager's memory.
//
//   live_rate_monitor --pid PID [--period S (60)] [--periods N (0 = until killed)] TOPIC...
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

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
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--pid" && i + 1 < argc) {
      pid = argv[++i];
    } else if (arg == "--period" && i + 1 < argc) {
      period_s = std::atof(argv[++i]);
    } else if (arg == "--periods" && i + 1 < argc) {
      periods = std::atoi(argv[++i]);
    } else if (arg == "--help" || arg.rfind("--", 0) == 0 || period_s <= 0.0) {
      std::fprintf(stderr, "usage: live_rate_monitor --pid PID [--period S] [--periods N] TOPIC...\n");
      return arg == "--help" ? 0 : 2;
    } else {
      topics.push_back(arg);
    }
  }
  if (pid.empty() || topics.empty()) {
    std::fprintf(stderr, "usage: live_rate_monitor --pid PID [--period S] [--periods N] TOPIC...\n");
    return 2;
  }
  ros::NodeHandle nh;
  std::vector<std::unique_ptr<std::atomic<long>>> counts;
  std::vector<ros::Subscriber> subscribers;
  for (const std::string& topic : topics) {
    counts.push_back(std::make_unique<std::atomic<long>>(0));
    std::atomic<long>* count = counts.back().get();
    subscribers.push_back(nh.subscribe<sensor_msgs::Image>(topic, 100, [count](const sensor_msgs::ImageConstPtr&) {
      ++*count;
    }));
  }
  ros::AsyncSpinner spinner(1);
  spinner.start();
  std::printf("%-7s %-7s", "period", "RSS_MB");
  for (const std::string& topic : topics) std::printf(" %s", topic.c_str());
  std::printf("\n");
  std::fflush(stdout);
  for (int k = 1; ros::ok() && (periods == 0 || k <= periods); ++k) {
    ros::WallDuration(period_s).sleep();
    std::printf("%-7d %-7ld", k, residentMegabytes(pid));
    for (std::size_t t = 0; t < topics.size(); ++t) {
      std::printf(" %*ld", static_cast<int>(topics[t].size()), counts[t]->exchange(0));
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  return 0;
}
