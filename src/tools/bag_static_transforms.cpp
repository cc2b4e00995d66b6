// bag_static_transforms: publishes a bag's static transforms, read from the file, latched on
// /tf_static for as long as it runs. launch/replay.launch runs it beside `rosbag play`, which
// publishes the bag's /tf_static only when it plays that message (started past it, on a
// publisher it advertises after its delay, so it reaches tf after the first data) and unlatched
// (lost by a late listener) when the bag's connection lost its latching flag (issue 14, defect 9:
// pairs, or a whole short replay, without gyro flow, "no IMU-to-camera transform").
//
//   bag_static_transforms --bag FILE [--topic /tf_static]
//
// Every transform of every message on the topic is merged (the newest per child frame) into one
// message, so that several recorded static publishers all reach a late subscriber.
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdio>
#include <exception>
#include <optional>
#include <string>

#include "deep_ois/ros/bag/bag_static_transforms.h"
#include "deep_ois/tools/support/command_line.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "bag_static_transforms", ros::init_options::AnonymousName);
  std::string bag_path;
  std::string topic = "/tf_static";
  deep_ois::ToolCommandLine command_line(
      "bag_static_transforms",
      "Publishes a bag's static transforms (every message on the topic, merged: the newest per "
      "child frame), read from the file, latched on the same topic until stopped. For replays: "
      "rosbag play publishes the bag's /tf_static only when it plays that message (started past "
      "it: late, with the first data; unlatched if the recording lost its latching flag).",
      "Exit status: 0 stopped, or nothing to publish (said on stderr); 1 the bag cannot be read; "
      "2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--bag", bag_path, "the bag to read")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE");
  app.add_option("--topic", topic, "the static transform topic, read and published")
      ->capture_default_str()
      ->type_name("TOPIC");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  deep_ois::BagStaticTransforms transforms;
  try {
    transforms = deep_ois::readBagStaticTransforms(bag_path, topic);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bag_static_transforms: %s\n", e.what());
    return 1;
  }
  if (!transforms.recovery_note.empty()) ROS_WARN("bag_static_transforms: %s", transforms.recovery_note.c_str());
  if (transforms.message.transforms.empty()) {
    ROS_WARN("bag_static_transforms: %s: %s: nothing to publish (the gyro flow nodelet then needs its "
             "~imu_to_camera_rotation, or the transform from another publisher)",
             bag_path.c_str(), transforms.summary(topic).c_str());
    return 0;
  }
  ros::NodeHandle nh;
  ros::Publisher publisher = nh.advertise<tf2_msgs::TFMessage>(topic, 1, /*latch=*/true);
  publisher.publish(transforms.message);
  ROS_INFO("bag_static_transforms: %s: publishing %s", bag_path.c_str(), transforms.summary(topic).c_str());
  ros::spin();
  return 0;
}
