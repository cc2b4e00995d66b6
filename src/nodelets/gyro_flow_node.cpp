// Stand-alone node over the same class as the deep_ois/gyro_flow nodelet.
#include <ros/ros.h>

#include <stdexcept>

#include "deep_ois/ros/live/gyro_flow_ros.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "gyro_flow");
  // Held outside the try: the last NodeHandle going away shuts ROS down, and rosconsole with it,
  // so a FATAL logged after the wrapper's own handles were unwound by its exception would be lost.
  ros::NodeHandle nh, private_nh("~");
  try {
    deep_ois::GyroFlowRos gyro_flow(nh, private_nh);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
