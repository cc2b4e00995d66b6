#include "deep_ois/ros/messages/recording_bag_messages.h"

#include <Eigen/Geometry>
#include <cmath>

namespace deep_ois {

ros::Time toRosTime(double base_s, double offset_s) {
  const double whole = std::floor(base_s);
  return ros::Time(static_cast<uint32_t>(whole), 0) + ros::Duration(base_s - whole + offset_s);
}

sensor_msgs::Imu makeGyroImuMessage(const ros::Time& stamp, const std::string& frame_id,
                                    const Eigen::Vector3d& angular_velocity_rad_s,
                                    double gyro_variance_rad2_s2) {
  sensor_msgs::Imu imu;
  imu.header.stamp = stamp;
  imu.header.frame_id = frame_id;
  imu.orientation_covariance[0] = -1.0;  // no orientation estimate
  imu.angular_velocity.x = angular_velocity_rad_s.x();
  imu.angular_velocity.y = angular_velocity_rad_s.y();
  imu.angular_velocity.z = angular_velocity_rad_s.z();
  for (int i = 0; i < 3; ++i) imu.angular_velocity_covariance[4 * i] = gyro_variance_rad2_s2;
  return imu;
}

tf2_msgs::TFMessage makeImuToCameraTransform(const ros::Time& stamp, const std::string& imu_frame_id,
                                             const std::string& camera_frame_id,
                                             const Eigen::Matrix3d& imu_to_camera_rotation) {
  geometry_msgs::TransformStamped transform;
  transform.header.stamp = stamp;
  transform.header.frame_id = imu_frame_id;  // parent
  transform.child_frame_id = camera_frame_id;
  const Eigen::Quaterniond q(Eigen::Matrix3d(imu_to_camera_rotation.transpose()));
  transform.transform.rotation.w = q.w();
  transform.transform.rotation.x = q.x();
  transform.transform.rotation.y = q.y();
  transform.transform.rotation.z = q.z();
  tf2_msgs::TFMessage tf;
  tf.transforms.push_back(transform);
  return tf;
}

}  // namespace deep_ois
