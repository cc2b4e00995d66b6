// The messages a robot's recording carries besides its images (gyro Imu, the static IMU -> camera
// transform) and how they are stamped and written: shared by the simulator's bag writer and the
// converter of real recordings, so both write the topics the nodelets read in the same way.
#pragma once

#include <rosbag/bag.h>
#include <ros/time.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Core>
#include <boost/make_shared.hpp>
#include <string>

namespace deep_ois {

// `base_s + offset_s` seconds as ROS time, rounded to the nanosecond. The base's whole seconds are
// kept as an integer and only its fraction is added to the offset in floating point, so stamps
// keep nanosecond resolution even for epoch-sized bases.
ros::Time toRosTime(double base_s, double offset_s);

// A gyro reading as sensor_msgs/Imu: angular velocity in rad/s in `frame_id` (the IMU frame), no
// orientation estimate (orientation_covariance[0] = -1, REP 145). `gyro_variance_rad2_s2` goes on
// the angular velocity covariance diagonal; 0 leaves it all zero, which Imu.msg defines as
// "covariance unknown". The accelerometer part is left for the caller (all zero).
sensor_msgs::Imu makeGyroImuMessage(const ros::Time& stamp, const std::string& frame_id,
                                    const Eigen::Vector3d& angular_velocity_rad_s,
                                    double gyro_variance_rad2_s2 = 0.0);

// The static transform IMU frame (parent) -> camera optical frame (child) for a gyro-to-camera
// rotation R_cam_imu (a vector v in the IMU frame is R_cam_imu * v in the camera frame): the
// child's orientation in the parent is R_cam_imu^T, so that tf's lookupTransform(camera, imu)
// yields R_cam_imu. No translation (only the rotation matters for the gyro flow).
tf2_msgs::TFMessage makeImuToCameraTransform(const ros::Time& stamp, const std::string& imu_frame_id,
                                             const std::string& camera_frame_id,
                                             const Eigen::Matrix3d& imu_to_camera_rotation);

// Writes `message` as a latched publisher (tf_static's) would have recorded it, so that
// `rosbag play` republishes it latched and late subscribers still get it. `caller_id` names the
// pretend publisher.
template <typename Message>
void writeLatched(rosbag::Bag& bag, const std::string& topic, const ros::Time& time,
                  const Message& message, const std::string& caller_id) {
  // A custom connection header replaces rosbag's own: it must carry the type too.
  auto header = boost::make_shared<ros::M_string>();
  (*header)["type"] = ros::message_traits::datatype<Message>();
  (*header)["md5sum"] = ros::message_traits::md5sum<Message>();
  (*header)["message_definition"] = ros::message_traits::definition<Message>();
  (*header)["callerid"] = caller_id;
  (*header)["latching"] = "1";
  bag.write(topic, time, message, header);
}

}  // namespace deep_ois
