// The camera messages of the rostests' synthetic streams (gyro_flow_rostest_helpers.h,
// live_pipeline_rostest_helpers.h): the frame ids, a textured mono8 image and a plumb_bob
// camera_info without distortion.
#pragma once

#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <Eigen/Core>
#include <boost/make_shared.hpp>
#include <cstdint>
#include <string>

namespace deep_ois {
namespace synthetic {

constexpr char kImuFrame[] = "imu_link";
constexpr char kCameraFrame[] = "camera_optical_frame";

// `width` x `height` pixels of a texture that varies along both axes (trackable; the gyro flow
// ignores the content). `encoding` is written as given, so a test can send a wrong one.
inline sensor_msgs::ImagePtr makeImage(const ros::Time& stamp, uint32_t width, uint32_t height,
                                       const std::string& encoding = "mono8") {
  auto image = boost::make_shared<sensor_msgs::Image>();
  image->header.stamp = stamp;
  image->header.frame_id = kCameraFrame;
  image->width = width;
  image->height = height;
  image->encoding = encoding;
  image->step = width;
  image->data.resize(static_cast<std::size_t>(width) * height);
  for (std::size_t k = 0; k < image->data.size(); ++k) image->data[k] = static_cast<uint8_t>((k * 7) ^ (k / width));
  return image;
}

// Plumb_bob with zero coefficients, the given K, R = identity, P = [K | 0].
inline sensor_msgs::CameraInfoPtr makeInfo(const ros::Time& stamp, uint32_t width, uint32_t height,
                                           const Eigen::Matrix3d& K) {
  auto info = boost::make_shared<sensor_msgs::CameraInfo>();
  info->header.stamp = stamp;
  info->header.frame_id = kCameraFrame;
  info->width = width;
  info->height = height;
  info->distortion_model = "plumb_bob";
  info->D.assign(5, 0.0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      info->K[3 * r + c] = K(r, c);
      info->P[4 * r + c] = K(r, c);
    }
  }
  info->R[0] = info->R[4] = info->R[8] = 1.0;
  return info;
}

}  // namespace synthetic
}  // namespace deep_ois
