// Android's camera geometry conventions: how a frame stored upright relates to the sensor's rows
// (SENSOR_ORIENTATION), and the back camera's IMU-to-camera rotation. Pure core: no ROS.
//
// Why frames go back to the sensor's orientation: a rolling shutter reads the sensor's rows in
// order. A portrait video from a landscape sensor (SENSOR_ORIENTATION 90 or 270) is the sensor image
// turned by a quarter: its readout sweeps across columns. The package's rolling-shutter model
// (gyro flow, calibrate) reads rows top to bottom, so the importers turn the frames (and the
// intrinsics) back to the sensor's orientation, where that holds.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

namespace deep_ois {

// The turn that takes a stored upright frame back to the sensor's orientation, for a sensor whose
// image must be turned `sensor_orientation_deg` (0, 90, 180, 270) clockwise to be upright.
struct SensorOrientationTurn {
  int sensor_orientation_deg = 0;
  // The stored image -> the sensor's image.
  cv::Mat apply(const cv::Mat& stored) const;
  cv::Size sensorSize(cv::Size stored) const;
  // fx, fy, cx, cy of the stored image -> the same of the sensor's image (pixel centres at integers).
  Eigen::Vector4d intrinsics(const Eigen::Vector4d& stored, cv::Size stored_size) const;
  std::string describe() const;  // e.g. "turned 90 deg counter-clockwise back to the sensor's rows"
};

// Throws std::invalid_argument unless the orientation is 0, 90, 180 or 270.
SensorOrientationTurn sensorOrientationTurn(int sensor_orientation_deg);

// R_cam_imu of an Android back camera: the gyro in the phone's sensor frame (x right, y up, z out of
// the screen, natural orientation) -> the optical frame (x right, y down, z forward) of the sensor's
// image for that SENSOR_ORIENTATION. 90 (most phones) gives [[0,-1,0],[-1,0,0],[0,0,-1]].
Eigen::Matrix3d androidBackCameraImuToCamera(int sensor_orientation_deg);

}  // namespace deep_ois
