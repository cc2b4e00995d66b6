// Listens to a gyro_flow topic and prints a summary of what was published: how many frame pairs
// of the bag got a flow, the flow magnitudes, and how much the rolling-shutter patches differ.
// Exits when every pair of the bag has arrived or the topic stays silent; the demo launch marks
// it required, so its exit ends the demo. Flags: --help; ROS remappings (gyro_flow:=/x,
// __name:=y) go to ros::init.
#include <deep_ois/GyroFlow.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

struct Options {
  std::string bag;
  std::string image_topic = "/camera/image_raw";
  double idle_timeout_s = 5.0;
  double start_timeout_s = 60.0;
};

struct PairStats {
  double stamp_s;
  double mean_flow_px;     // mean |flow| over the grid, grid pixels
  double max_flow_px;      // max |flow|, grid pixels
  double patch_spread_px;  // largest displacement difference between patches at the image centre,
                           // camera pixels
};

}  // namespace

constexpr char kDescription[] =
    "Listens to a gyro_flow topic (remap it: gyro_flow:=/deep_ois/gyro_flow) and prints a summary "
    "of "
    "what was published: how many frame pairs of the bag got a flow, the flow magnitudes (grid "
    "pixels), and how much the rolling-shutter patches differ (camera pixels). Exits when every "
    "pair of the bag has arrived or the topic stays silent; the demo launch marks it required, so "
    "its exit ends the demo. ROS arguments (name:=value) are passed to ros::init.";

int main(int argc, char** argv) {
  Options options;
  deep_ois::ToolCommandLine command_line(
      "gyro_flow_summary", kDescription,
      "Exit status: 0 every pair summarised, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--bag", options.bag, "the bag being played (its frames are counted)")
      ->required()
      ->type_name("FILE.bag");
  app.add_option("--image-topic", options.image_topic, "image topic of the bag")
      ->capture_default_str()
      ->type_name("TOPIC");
  command_line
      .addNumber("--idle-timeout", options.idle_timeout_s,
                 "exit when the topic stays silent this long after a message, seconds")
      ->type_name("SECONDS");
  command_line
      .addNumber("--start-timeout", options.start_timeout_s,
                 "exit when no message arrives this long after the start, seconds")
      ->type_name("SECONDS");
  // Remappings and special names (gyro_flow:=/x, __name:=y, as roslaunch passes) are ros::init's;
  // CLI11 sees the rest.
  std::vector<std::string> arguments;
  ros::removeROSArgs(argc, argv, arguments);
  if (const std::optional<int> status = command_line.parse(arguments)) return *status;
  ros::init(argc, argv, "gyro_flow_summary");

  std::size_t frames_in_bag = 0;
  try {
    rosbag::Bag bag(options.bag, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(options.image_topic));
    frames_in_bag = view.size();
  } catch (const rosbag::BagException& e) {
    std::fprintf(stderr, "gyro_flow_summary: cannot read %s: %s\n", options.bag.c_str(), e.what());
    return 1;
  }
  const std::size_t expected_pairs = frames_in_bag > 0 ? frames_in_bag - 1 : 0;

  std::mutex mutex;
  std::vector<PairStats> pairs;
  std::string first_problem;
  ros::WallTime last_message = ros::WallTime::now();
  deep_ois::GyroFlow first_message;

  ros::NodeHandle nh;
  ros::Subscriber sub = nh.subscribe<deep_ois::GyroFlow>(
      "gyro_flow", 100, [&](const deep_ois::GyroFlowConstPtr& msg) {
        std::vector<Eigen::Matrix3d> homographies;
        cv::Mat flow;
        const std::string problem = deep_ois::readGyroFlowMsg(*msg, homographies, flow);
        std::lock_guard<std::mutex> lock(mutex);
        last_message = ros::WallTime::now();
        if (!problem.empty()) {
          if (first_problem.empty()) first_problem = problem;
          return;
        }
        if (pairs.empty()) first_message = *msg;
        PairStats stats{msg->header.stamp.toSec(), 0.0, 0.0, 0.0};
        for (int y = 0; y < flow.rows; ++y) {
          for (int x = 0; x < flow.cols; ++x) {
            const cv::Vec2f f = flow.at<cv::Vec2f>(y, x);
            const double magnitude = std::hypot(f[0], f[1]);
            stats.mean_flow_px += magnitude;
            stats.max_flow_px = std::max(stats.max_flow_px, magnitude);
          }
        }
        stats.mean_flow_px /= static_cast<double>(flow.total());
        const Eigen::Vector2d centre(msg->image_width / 2.0, msg->image_height / 2.0);
        for (const auto& Hi : homographies) {
          for (const auto& Hj : homographies) {
            const double spread = ((Hi * centre.homogeneous()).hnormalized() -
                                   (Hj * centre.homogeneous()).hnormalized())
                                      .norm();
            stats.patch_spread_px = std::max(stats.patch_spread_px, spread);
          }
        }
        pairs.push_back(stats);
      });

  ros::AsyncSpinner spinner(1);
  spinner.start();
  const ros::WallTime started = ros::WallTime::now();
  std::printf("gyro_flow_summary: listening on %s for %zu frame pairs of %s\n",
              sub.getTopic().c_str(), expected_pairs, options.bag.c_str());
  std::fflush(stdout);
  while (ros::ok()) {
    ros::WallDuration(0.1).sleep();
    std::lock_guard<std::mutex> lock(mutex);
    if (pairs.size() >= expected_pairs && expected_pairs > 0) break;
    const double idle = (ros::WallTime::now() - last_message).toSec();
    if (!pairs.empty() && idle > options.idle_timeout_s) break;
    if (pairs.empty() && (ros::WallTime::now() - started).toSec() > options.start_timeout_s) break;
  }
  spinner.stop();

  std::lock_guard<std::mutex> lock(mutex);
  std::printf("\n==== gyro_flow summary ====\n");
  std::printf("bag:                 %s (%zu frames on %s)\n", options.bag.c_str(), frames_in_bag,
              options.image_topic.c_str());
  std::printf("gyro flows received: %zu of %zu frame pairs\n", pairs.size(), expected_pairs);
  if (!first_problem.empty()) std::printf("malformed messages:  %s\n", first_problem.c_str());
  if (pairs.empty()) {
    std::printf("no gyro flow received: check the gyro_flow nodelet's warnings above\n");
    return 1;
  }
  const auto& m = first_message;
  std::printf("camera:              %ux%u, fx %.2f fy %.2f cx %.2f cy %.2f px, frame %s\n",
              m.image_width, m.image_height, m.K[0], m.K[4], m.K[2], m.K[5],
              m.header.frame_id.c_str());
  std::printf("model:               %u patches, readout %.4f s, time offset %.4f s\n",
              m.patch_count, m.readout_time, m.time_offset);
  std::printf("flow grid:           %ux%u (%s)\n", m.flow.width, m.flow.height,
              m.flow.encoding.c_str());
  double mean = 0.0, max = 0.0, spread = 0.0;
  for (const auto& p : pairs) {
    mean += p.mean_flow_px;
    max = std::max(max, p.max_flow_px);
    spread += p.patch_spread_px;
  }
  std::printf("mean |flow|:         %.3f grid px (largest %.3f grid px)\n", mean / pairs.size(),
              max);
  std::printf(
      "rolling shutter:     patches disagree by %.3f camera px at the image centre on average\n",
      spread / pairs.size());
  std::printf("first/last pair:     %.6f .. %.6f s\n", pairs.front().stamp_s, pairs.back().stamp_s);
  std::printf("===========================\n");
  std::fflush(stdout);
  return pairs.size() == expected_pairs ? 0 : 3;
}
