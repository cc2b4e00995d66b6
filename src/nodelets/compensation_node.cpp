// Stand-alone node over the same class as the deep_ois/compensation nodelet.
#include <ros/ros.h>

#include <stdexcept>

#include "deep_ois/ros/live/compensation_ros.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "compensation");
  // Held outside the try: the last NodeHandle going away shuts ROS down, and rosconsole with it,
  // so a FATAL logged after the wrapper's own handles were unwound by its exception would be lost.
  ros::NodeHandle nh, private_nh("~");
  try {
    deep_ois::CompensationRos compensation(nh, private_nh);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
