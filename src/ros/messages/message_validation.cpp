#include "deep_ois/ros/messages/message_validation.h"

#include <sensor_msgs/image_encodings.h>

#include <cmath>
#include <cstring>
#include <sstream>
#include <vector>

#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
namespace {

namespace enc = sensor_msgs::image_encodings;

// Empty when every value is finite, else "<field>[<index>] is <value>".
template <typename Values>
std::string firstNonFinite(const char* field, const Values& values) {
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (!std::isfinite(values[k])) {
      std::ostringstream why;
      why << field << "[" << k << "] is " << values[k];
      return why.str();
    }
  }
  return {};
}

std::string stampsProblem(const std_msgs::Header& header, const ros::Time& previous_stamp) {
  std::ostringstream why;
  if (header.stamp.isZero()) return "header.stamp is zero";
  if (!(previous_stamp < header.stamp)) {
    why << "previous_stamp " << previous_stamp << " is not before header.stamp " << header.stamp;
    return why.str();
  }
  return {};
}

}  // namespace

std::string nonFiniteFloatImageProblem(const sensor_msgs::Image& image) {
  if (image.encoding != enc::TYPE_32FC1 && image.encoding != enc::TYPE_32FC2 &&
      image.encoding != enc::TYPE_32FC3 && image.encoding != enc::TYPE_32FC4) {
    return {};
  }
  const std::size_t values_per_row = static_cast<std::size_t>(image.width) * enc::numChannels(image.encoding);
  for (std::uint32_t y = 0; y < image.height; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * image.step;
    if (row + 4 * values_per_row > image.data.size()) return "image data ends before row " + std::to_string(y);
    for (std::size_t x = 0; x < values_per_row; ++x) {
      float v;
      std::memcpy(&v, &image.data[row + 4 * x], sizeof v);
      if (!std::isfinite(v)) {
        std::ostringstream why;
        why << "value " << x << " of row " << y << " is " << v;
        return why.str();
      }
    }
  }
  return {};
}

std::string gyroFlowProblem(const GyroFlow& msg) {
  std::ostringstream why;
  std::string problem = stampsProblem(msg.header, msg.previous_stamp);
  if (!problem.empty()) return problem;
  if (msg.image_width == 0 || msg.image_height == 0) {
    why << "image size " << msg.image_width << "x" << msg.image_height << " is zero";
    return why.str();
  }
  if (msg.patch_count == 0 || msg.homographies.size() != 9 * static_cast<std::size_t>(msg.patch_count)) {
    why << msg.homographies.size() << " homography values for patch_count " << msg.patch_count
        << " (expected 9 per patch, at least one patch)";
    return why.str();
  }
  if (!(problem = firstNonFinite("homographies", msg.homographies)).empty()) return problem;
  for (std::size_t i = 0; i < msg.patch_count; ++i) {
    if (msg.homographies[9 * i + 8] == 0.0) return "homography " + std::to_string(i) + " has H[2][2] = 0";
  }
  if (!(problem = firstNonFinite("K", msg.K)).empty()) return problem;
  if (!(msg.K[0] > 0.0) || !(msg.K[4] > 0.0)) {
    why << "K has focal lengths fx " << msg.K[0] << ", fy " << msg.K[4] << " (expected > 0)";
    return why.str();
  }
  if (!(problem = firstNonFinite("D", msg.D)).empty()) return problem;
  if (!std::isfinite(msg.readout_time) || msg.readout_time < 0.0) {
    why << "readout_time is " << msg.readout_time << " s (expected finite, >= 0)";
    return why.str();
  }
  if (!std::isfinite(msg.time_offset)) {
    why << "time_offset is " << msg.time_offset << " s";
    return why.str();
  }
  if (!(msg.patch_time_fraction >= 0.0 && msg.patch_time_fraction <= 1.0)) {
    why << "patch_time_fraction is " << msg.patch_time_fraction << " (expected in [0, 1])";
    return why.str();
  }
  if (!(problem = firstNonFinite("imu_to_camera_rotation", msg.imu_to_camera_rotation)).empty()) return problem;
  if (msg.angular_velocity.size() != 3 * msg.angular_velocity_times.size()) {
    why << msg.angular_velocity.size() << " angular_velocity values for " << msg.angular_velocity_times.size()
        << " angular_velocity_times (expected 3 per time)";
    return why.str();
  }
  if (!(problem = firstNonFinite("angular_velocity_times", msg.angular_velocity_times)).empty()) return problem;
  if (!(problem = firstNonFinite("angular_velocity", msg.angular_velocity)).empty()) return problem;
  for (std::size_t k = 1; k < msg.angular_velocity_times.size(); ++k) {
    if (!(msg.angular_velocity_times[k] > msg.angular_velocity_times[k - 1])) {
      why << "angular_velocity_times[" << k << "] " << msg.angular_velocity_times[k] << " is not after the one before";
      return why.str();
    }
  }
  if (msg.flow.encoding != enc::TYPE_32FC2) return "flow encoding is '" + msg.flow.encoding + "', expected 32FC2";
  if (!(problem = validateImage(msg.flow)).empty()) return "flow: " + problem;
  if (!(problem = nonFiniteFloatImageProblem(msg.flow)).empty()) return "flow: " + problem;
  return {};
}

std::string compensationPairCheckProblem(const CompensationPairCheck& msg) {
  std::ostringstream why;
  std::string problem = stampsProblem(msg.header, msg.previous_stamp);
  if (!problem.empty()) return problem;
  if (!(msg.confidence >= 0.0f && msg.confidence <= 1.0f)) {
    why << "confidence is " << msg.confidence << " (expected in [0, 1])";
    return why.str();
  }
  if (msg.inliers > msg.tracks) {
    why << msg.inliers << " inliers of " << msg.tracks << " tracks";
    return why.str();
  }
  if (msg.usable && !(std::isfinite(msg.model_residual) && msg.model_residual >= 0.0f &&
                      std::isfinite(msg.gyro_residual) && msg.gyro_residual >= 0.0f)) {
    why << "a usable check with residuals " << msg.model_residual << " (model) and " << msg.gyro_residual
        << " (gyro) px";
    return why.str();
  }
  for (const float fusion_px : {msg.fusion_mean_correction, msg.fusion_max_correction, msg.fusion_prior_sigma,
                                msg.fusion_prior_residual, msg.fusion_fused_residual}) {
    if (!(std::isfinite(fusion_px) && fusion_px >= 0.0f)) {
      why << "a fusion figure of " << fusion_px << " px (expected finite and >= 0)";
      return why.str();
    }
  }
  if (!msg.fused && (msg.fusion_refined || !msg.fusion_reason.empty())) return "fusion fields set on a pair not fused";
  return {};
}

}  // namespace deep_ois
