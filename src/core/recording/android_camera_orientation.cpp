#include "deep_ois/core/recording/android_camera_orientation.h"

#include <opencv2/core.hpp>
#include <stdexcept>

namespace deep_ois {

SensorOrientationTurn sensorOrientationTurn(int sensor_orientation_deg) {
  if (sensor_orientation_deg != 0 && sensor_orientation_deg != 90 && sensor_orientation_deg != 180 &&
      sensor_orientation_deg != 270) {
    throw std::invalid_argument("sensor orientation " + std::to_string(sensor_orientation_deg) +
                                " deg: expected 0, 90, 180 or 270");
  }
  return {sensor_orientation_deg};
}

// The upright image is the sensor's turned clockwise by the orientation, so going back turns it
// counter-clockwise by as much.
cv::Mat SensorOrientationTurn::apply(const cv::Mat& stored) const {
  cv::Mat out;
  switch (sensor_orientation_deg) {
    case 90: cv::rotate(stored, out, cv::ROTATE_90_COUNTERCLOCKWISE); return out;
    case 180: cv::rotate(stored, out, cv::ROTATE_180); return out;
    case 270: cv::rotate(stored, out, cv::ROTATE_90_CLOCKWISE); return out;
    default: return stored;
  }
}

cv::Size SensorOrientationTurn::sensorSize(cv::Size stored) const {
  return sensor_orientation_deg % 180 == 0 ? stored : cv::Size(stored.height, stored.width);
}

Eigen::Vector4d SensorOrientationTurn::intrinsics(const Eigen::Vector4d& k, cv::Size stored) const {
  const double fx = k[0], fy = k[1], cx = k[2], cy = k[3];
  const double w = stored.width, h = stored.height;
  switch (sensor_orientation_deg) {
    // ROTATE_90_COUNTERCLOCKWISE: stored (u, v) -> sensor (v, w - 1 - u).
    case 90: return {fy, fx, cy, w - 1.0 - cx};
    case 180: return {fx, fy, w - 1.0 - cx, h - 1.0 - cy};
    // ROTATE_90_CLOCKWISE: stored (u, v) -> sensor (h - 1 - v, u).
    case 270: return {fy, fx, h - 1.0 - cy, cx};
    default: return k;
  }
}

std::string SensorOrientationTurn::describe() const {
  switch (sensor_orientation_deg) {
    case 90: return "frames turned 90 deg counter-clockwise back to the sensor's orientation (SENSOR_ORIENTATION 90): rows are read out top to bottom";
    case 180: return "frames turned 180 deg back to the sensor's orientation (SENSOR_ORIENTATION 180): rows are read out top to bottom";
    case 270: return "frames turned 90 deg clockwise back to the sensor's orientation (SENSOR_ORIENTATION 270): rows are read out top to bottom";
    default: return "frames as stored (SENSOR_ORIENTATION 0): rows are read out top to bottom";
  }
}

Eigen::Matrix3d androidBackCameraImuToCamera(int sensor_orientation_deg) {
  sensorOrientationTurn(sensor_orientation_deg);  // validates
  // The upright (natural orientation) image's optical frame: x = device x, y = -device y, z = -device z.
  Eigen::Matrix3d upright;
  upright << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  // The sensor's image axes in the upright image's (the counter-clockwise turn of apply()).
  Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
  if (sensor_orientation_deg == 90) turn << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  if (sensor_orientation_deg == 180) turn << -1, 0, 0, 0, -1, 0, 0, 0, 1;
  if (sensor_orientation_deg == 270) turn << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  return turn * upright;
}

}  // namespace deep_ois
