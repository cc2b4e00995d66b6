#include "deep_ois/ros/messages/conversions.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/distortion_models.h>
#include <sensor_msgs/image_encodings.h>

#include <boost/make_shared.hpp>
#include <opencv2/imgproc.hpp>
#include <limits>
#include <cmath>
#include <sstream>

namespace deep_ois {

namespace enc = sensor_msgs::image_encodings;

ImuSample toImuSample(const sensor_msgs::Imu& imu, const ros::Time& time_base) {
  ImuSample sample;
  sample.stamp_s = (imu.header.stamp - time_base).toSec();
  sample.angular_velocity_rad_s =
      Eigen::Vector3d(imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z);
  return sample;
}

std::string validateImage(const sensor_msgs::Image& image) {
  std::ostringstream why;
  if (image.width == 0 || image.height == 0) {
    why << "image has zero size (" << image.width << "x" << image.height << ")";
    return why.str();
  }
  int channels = 0, bit_depth = 0;
  try {
    channels = enc::numChannels(image.encoding);
    bit_depth = enc::bitDepth(image.encoding);
  } catch (const std::exception&) {
    why << "unsupported image encoding '" << image.encoding << "'";
    return why.str();
  }
  // Packed YUV formats report 2 channels of 8 bits; everything else is channels x depth.
  const std::size_t bytes_per_pixel = static_cast<std::size_t>(channels) * (bit_depth / 8);
  if (image.step < image.width * bytes_per_pixel) {
    why << "image step " << image.step << " bytes is smaller than width " << image.width << " x "
        << bytes_per_pixel << " bytes per pixel of '" << image.encoding << "'";
    return why.str();
  }
  if (image.data.size() < static_cast<std::size_t>(image.step) * image.height) {
    why << "image data holds " << image.data.size() << " bytes, fewer than step " << image.step
        << " x height " << image.height;
    return why.str();
  }
  return {};
}

std::string toCameraModel(const sensor_msgs::CameraInfo& info, CameraModel& camera, std::string* note) {
  std::ostringstream why;
  const std::string& name = info.distortion_model;
  DistortionModel model = DistortionModel::kPlumbBob;
  std::vector<double> distortion;
  if (name.empty() || name == "none") {
    // no distortion
  } else if (name == sensor_msgs::distortion_models::PLUMB_BOB) {
    distortion = info.D;
  } else if (name == sensor_msgs::distortion_models::RATIONAL_POLYNOMIAL) {
    model = DistortionModel::kRationalPolynomial;
    distortion = info.D;
  } else if (name == sensor_msgs::distortion_models::EQUIDISTANT) {
    model = DistortionModel::kEquidistant;
    distortion = info.D;
  } else {
    why << "unsupported distortion model '" << name
        << "' (supported: plumb_bob, rational_polynomial, equidistant, or none)";
    return why.str();
  }
  camera = CameraModel(static_cast<int>(info.width), static_cast<int>(info.height),
                       rowMajorToMatrix(info.K.data()), model, distortion);
  const std::string problem = camera.validate();
  if (problem.empty() && note != nullptr) {
    note->clear();
    const Eigen::Matrix3d R = rowMajorToMatrix(info.R.data());
    Eigen::Matrix3d P_left;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) P_left(r, c) = info.P[4 * r + c];
    const bool r_says_something = !R.isZero(0.0) && !R.isIdentity(1e-9);
    const bool p_says_something = !P_left.isZero(0.0) && !P_left.isApprox(camera.K(), 1e-9);
    if (r_says_something || p_says_something) {
      std::ostringstream text;
      text << "CameraInfo " << (r_says_something ? "R is not the identity" : "")
           << (r_says_something && p_says_something ? " and " : "")
           << (p_says_something ? "P differs from K" : "")
           << " (a rectified camera): the gyro flow is for the raw image and uses K and D only; "
              "R and P are not used";
      *note = text.str();
    }
  }
  return problem;
}

Eigen::Matrix3d rowMajorToMatrix(const double* values) {
  Eigen::Matrix3d matrix;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) matrix(r, c) = values[3 * r + c];
  return matrix;
}

void matrixToRowMajor(const Eigen::Matrix3d& matrix, double* values) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) values[3 * r + c] = matrix(r, c);
}

std::vector<double> flattenMatrices(const std::vector<Eigen::Matrix3d>& matrices) {
  std::vector<double> values(9 * matrices.size());
  for (std::size_t i = 0; i < matrices.size(); ++i) matrixToRowMajor(matrices[i], &values[9 * i]);
  return values;
}

std::vector<Eigen::Matrix3d> unflattenMatrices(const std::vector<double>& values) {
  std::vector<Eigen::Matrix3d> matrices;
  for (std::size_t i = 0; i + 9 <= values.size(); i += 9) matrices.push_back(rowMajorToMatrix(&values[i]));
  return matrices;
}

std::vector<double> flattenPoints(const std::vector<Eigen::Vector2d>& points) {
  std::vector<double> values;
  values.reserve(2 * points.size());
  for (const Eigen::Vector2d& p : points) {
    values.push_back(p.x());
    values.push_back(p.y());
  }
  return values;
}

std::vector<Eigen::Vector2d> unflattenPoints(const std::vector<double>& values) {
  std::vector<Eigen::Vector2d> points;
  for (std::size_t i = 0; i + 2 <= values.size(); i += 2) points.emplace_back(values[i], values[i + 1]);
  return points;
}

void fillGyroFlowMsg(const GyroFlowMetadata& metadata, const std::vector<Eigen::Matrix3d>& homographies,
                     const cv::Mat& flow, GyroFlow& msg) {
  msg.header = metadata.header;
  msg.previous_stamp = metadata.previous_stamp;
  msg.image_width = static_cast<uint32_t>(metadata.camera.width());
  msg.image_height = static_cast<uint32_t>(metadata.camera.height());
  msg.patch_count = static_cast<uint32_t>(homographies.size());
  msg.homographies = flattenMatrices(homographies);
  matrixToRowMajor(metadata.camera.K(), msg.K.data());
  msg.distortion_model = metadata.distortion_model;
  msg.D = metadata.distortion;
  const RollingShutterConfig& rs = metadata.rolling_shutter;
  msg.readout_time = rs.readout_time_s;
  msg.time_offset = rs.time_offset_s;
  msg.patch_time_fraction = rs.patch_time == PatchTimeReference::kPatchCentre ? 0.5 : 0.0;
  matrixToRowMajor(rs.imu_to_camera_rotation, msg.imu_to_camera_rotation.data());
  msg.calibration_epoch = metadata.calibration_epoch;
  msg.angular_velocity_times.clear();
  msg.angular_velocity.clear();
  for (const CameraRateSample& rate : metadata.camera_rates) {
    msg.angular_velocity_times.push_back(rate.stamp_s);
    for (int k = 0; k < 3; ++k) msg.angular_velocity.push_back(rate.rate_rad_s(k));
  }

  msg.flow.header = metadata.header;
  msg.flow.height = static_cast<uint32_t>(flow.rows);
  msg.flow.width = static_cast<uint32_t>(flow.cols);
  msg.flow.encoding = sensor_msgs::image_encodings::TYPE_32FC2;
  msg.flow.is_bigendian = false;
  msg.flow.step = static_cast<uint32_t>(flow.cols * flow.elemSize());
  msg.flow.data.resize(static_cast<std::size_t>(msg.flow.step) * flow.rows);
  for (int y = 0; y < flow.rows; ++y) {
    std::memcpy(&msg.flow.data[static_cast<std::size_t>(y) * msg.flow.step], flow.ptr(y), msg.flow.step);
  }
}

std::vector<CameraRateSample> readGyroFlowRates(const GyroFlow& msg, std::string* problem) {
  std::vector<CameraRateSample> rates;
  auto fail = [&](const std::string& why) {
    if (problem) *problem = why;
    return std::vector<CameraRateSample>{};
  };
  if (msg.angular_velocity.size() != 3 * msg.angular_velocity_times.size()) {
    return fail("GyroFlow has " + std::to_string(msg.angular_velocity.size()) +
                " angular_velocity values for " + std::to_string(msg.angular_velocity_times.size()) +
                " times (expected 3 per time)");
  }
  const double stamp_s = msg.header.stamp.toSec();
  for (std::size_t k = 0; k < msg.angular_velocity_times.size(); ++k) {
    CameraRateSample rate;
    rate.stamp_s = stamp_s + msg.angular_velocity_times[k];
    rate.rate_rad_s = Eigen::Vector3d(msg.angular_velocity[3 * k], msg.angular_velocity[3 * k + 1],
                                      msg.angular_velocity[3 * k + 2]);
    if (!std::isfinite(rate.stamp_s) || !rate.rate_rad_s.allFinite() ||
        (!rates.empty() && !(rate.stamp_s > rates.back().stamp_s))) {
      return fail("GyroFlow angular velocity sample " + std::to_string(k) +
                  " is not finite or not after the previous one");
    }
    rates.push_back(rate);
  }
  if (problem) problem->clear();
  return rates;
}

std::string readGyroFlowMsg(const GyroFlow& msg, std::vector<Eigen::Matrix3d>& homographies,
                            cv::Mat& flow_view) {
  std::ostringstream why;
  if (msg.patch_count == 0 || msg.homographies.size() != 9 * msg.patch_count) {
    why << "GyroFlow has " << msg.homographies.size() << " homography values for patch_count "
        << msg.patch_count << " (expected 9 per patch)";
    return why.str();
  }
  if (!(msg.previous_stamp < msg.header.stamp)) {
    why << "GyroFlow previous_stamp " << msg.previous_stamp << " is not before its stamp " << msg.header.stamp;
    return why.str();
  }
  if (msg.flow.encoding != sensor_msgs::image_encodings::TYPE_32FC2) {
    why << "GyroFlow flow encoding is '" << msg.flow.encoding << "', expected 32FC2";
    return why.str();
  }
  const std::string image_problem = validateImage(msg.flow);
  if (!image_problem.empty()) return "GyroFlow flow: " + image_problem;
  homographies = unflattenMatrices(msg.homographies);
  flow_view = cv::Mat(static_cast<int>(msg.flow.height), static_cast<int>(msg.flow.width), CV_32FC2,
                      const_cast<uint8_t*>(msg.flow.data.data()), msg.flow.step);
  return {};
}

cv_bridge::CvImageConstPtr toRgb8ForDisplay(const sensor_msgs::ImageConstPtr& image, DisplayRange& range) {
  namespace enc = sensor_msgs::image_encodings;
  if (enc::isColor(image->encoding) || enc::isMono(image->encoding)) return cv_bridge::toCvShare(image, enc::RGB8);
  const cv_bridge::CvImageConstPtr source = cv_bridge::toCvShare(image);
  if (source->image.channels() != 1) {
    throw cv_bridge::Exception("a " + image->encoding + " frame has no colour meaning to draw (" +
                               std::to_string(source->image.channels()) + " channels)");
  }
  cv::Mat values;
  source->image.convertTo(values, CV_64F);
  if (!range.set) {
    // NaN (no depth) and inf are left out of the range; NaN is drawn black.
    const cv::Mat finite = (values == values) & (cv::abs(values) < std::numeric_limits<double>::max());
    double black = 0.0, white = 0.0;
    if (cv::countNonZero(finite) > 0) cv::minMaxLoc(values, &black, &white, nullptr, nullptr, finite);
    range = {true, black, white};
  }
  const double span = range.white > range.black ? range.white - range.black : 1.0;
  cv::Mat grey;
  values.convertTo(grey, CV_8U, 255.0 / span, -255.0 * range.black / span);
  auto out = boost::make_shared<cv_bridge::CvImage>(image->header, enc::RGB8);
  cv::cvtColor(grey, out->image, cv::COLOR_GRAY2RGB);
  return out;
}

sensor_msgs::ImagePtr makeImageMsg(const std_msgs::Header& header, const std::string& encoding, cv::Size size,
                                   cv::Mat& view) {
  const int type = cv_bridge::getCvType(encoding);
  auto msg = boost::make_shared<sensor_msgs::Image>();
  msg->header = header;
  msg->encoding = encoding;
  msg->height = static_cast<std::uint32_t>(size.height);
  msg->width = static_cast<std::uint32_t>(size.width);
  msg->is_bigendian = 0;
  msg->step = static_cast<std::uint32_t>(size.width * CV_ELEM_SIZE(type));
  msg->data.resize(static_cast<std::size_t>(msg->step) * size.height);
  view = cv::Mat(size, type, msg->data.data(), msg->step);
  return msg;
}

}  // namespace deep_ois
