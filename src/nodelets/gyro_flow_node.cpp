// Stand-alone node over the same class as the deep_ois/gyro_flow nodelet.
#include <ros/ros.h>

#include <stdexcept>

#include "deep_ois/ros/live/gyro_flow_ros.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "gyro_flow");
  try {
    deep_ois::GyroFlowRos gyro_flow(ros::NodeHandle(), ros::NodeHandle("~"));
    ros::spin();
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
