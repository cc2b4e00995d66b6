// Stand-alone node over the same class as the deep_ois/compensation nodelet.
#include <ros/ros.h>

#include <stdexcept>

#include "deep_ois/ros/live/compensation_ros.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "compensation");
  try {
    deep_ois::CompensationRos compensation(ros::NodeHandle(), ros::NodeHandle("~"));
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
