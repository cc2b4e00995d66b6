// Conversions between ROS messages and the plain types of the core library.
#pragma once

#include <cv_bridge/cv_bridge.h>

#include <deep_ois/GyroFlow.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {

// Gyro reading of an Imu message: stamp in seconds since `time_base`, rate in rad/s in the
// message's frame. A recent time base keeps the stamps' doubles at nanosecond resolution (epoch
// seconds would leave only ~0.2 us).
ImuSample toImuSample(const sensor_msgs::Imu& imu, const ros::Time& time_base);

// Empty when the image header describes a usable image (known encoding, positive size, a step
// and data size that hold width x height pixels); otherwise a sentence naming the problem.
std::string validateImage(const sensor_msgs::Image& image);

// Builds the camera model of a CameraInfo (K and D; distortion models plumb_bob,
// rational_polynomial, equidistant, or none/empty). Returns an empty string on success, or a
// sentence naming the problem (unsupported distortion model, wrong number of coefficients,
// non-finite or degenerate K, zero size).
//
// R and P describe a rectified image; the gyro flow is for the raw image the CameraInfo comes
// with, so they are not used. When they say something (R not the identity, or the left 3x3 of P
// not K), `note` (if given) receives a sentence naming the field, for the caller to log.
std::string toCameraModel(const sensor_msgs::CameraInfo& info, CameraModel& camera, std::string* note = nullptr);

// Everything a GyroFlow message states besides its flow and homographies.
struct GyroFlowMetadata {
  std_msgs::Header header;  // stamp of frame b, camera optical frame id
  ros::Time previous_stamp;
  CameraModel camera;
  std::string distortion_model;
  std::vector<double> distortion;  // CameraInfo D as received
  RollingShutterConfig rolling_shutter;
  std::uint32_t calibration_epoch = 0;  // GyroFlow.calibration_epoch: +1 per calibration change
  // The gyro stream behind the pair (GyroFlow.angular_velocity*): camera-frame rates, stamps in
  // IMU-clock seconds relative to header.stamp.
  std::vector<CameraRateSample> camera_rates;
};

// Fills a GyroFlow message; `flow` is CV_32FC2 on the working grid (copied into the message).
void fillGyroFlowMsg(const GyroFlowMetadata& metadata, const std::vector<Eigen::Matrix3d>& homographies,
                     const cv::Mat& flow, GyroFlow& msg);

// The message's gyro stream with absolute IMU-clock stamps (header.stamp + each time), seconds;
// empty when the publisher sent none. A malformed stream (3 values per time expected, times
// increasing) gives an empty result and a sentence in `problem`.
std::vector<CameraRateSample> readGyroFlowRates(const GyroFlow& msg, std::string* problem = nullptr);

// The inverse of fillGyroFlowMsg for the parts consumers need: homographies (in camera pixels) and
// a CV_32FC2 view sharing the message's flow data. Returns an empty string on success, or a
// sentence naming what is inconsistent in the message.
std::string readGyroFlowMsg(const GyroFlow& msg, std::vector<Eigen::Matrix3d>& homographies,
                            cv::Mat& flow_view);

// An outgoing image message of `size` and `encoding` (one cv_bridge knows) with `header`, and in
// `view` a cv::Mat header over the message's own pixel buffer: whatever is written into `view`
// (a remap, a colour conversion) is published without a copy. Throws cv_bridge::Exception for an
// unknown encoding.
sensor_msgs::ImagePtr makeImageMsg(const std_msgs::Header& header, const std::string& encoding, cv::Size size,
                                   cv::Mat& view);

// The display range of a frame whose encoding has no colour meaning (16UC1 and 32FC1 depth or
// thermal, 8UC1, ...): the values drawn black and white. Empty until toRgb8ForDisplay sets it.
struct DisplayRange {
  bool set = false;
  double black = 0.0, white = 0.0;
};

// The image as rgb8 for a picture (the ghost overlay). Colour and mono encodings are converted as
// cv_bridge does. Any other one-channel encoding is scaled linearly from `range` to 0-255; an
// empty `range` is set from this image's finite values first, so the two frames of a pair drawn
// with one range stay comparable. Shares the message's data where it can. Throws
// cv_bridge::Exception naming the encoding when it cannot be shown (several channels of no known
// meaning).
cv_bridge::CvImageConstPtr toRgb8ForDisplay(const sensor_msgs::ImageConstPtr& image, DisplayRange& range);

// Messages carry matrices and points as flat float64[] arrays: consecutive row-major 3x3 blocks,
// and (x, y) pairs. The unflatten functions ignore a trailing incomplete block.
std::vector<double> flattenMatrices(const std::vector<Eigen::Matrix3d>& matrices);
std::vector<Eigen::Matrix3d> unflattenMatrices(const std::vector<double>& values);
std::vector<double> flattenPoints(const std::vector<Eigen::Vector2d>& points);
std::vector<Eigen::Vector2d> unflattenPoints(const std::vector<double>& values);

// Row-major 9 values <-> 3x3.
Eigen::Matrix3d rowMajorToMatrix(const double* values);
void matrixToRowMajor(const Eigen::Matrix3d& matrix, double* values);

}  // namespace deep_ois
