#include "deep_ois/core/flow/flow_color.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace deep_ois {

cv::Mat colorizeFlow(const cv::Mat& flow, double max_magnitude_px) {
  cv::Mat rgb;
  colorizeFlow(flow, max_magnitude_px, rgb);
  return rgb;
}

void colorizeFlow(const cv::Mat& flow, double max_magnitude_px, cv::Mat& rgb) {
  if (flow.type() != CV_32FC2) throw std::invalid_argument("colorizeFlow: flow must be CV_32FC2");
  cv::Mat channels[2];
  cv::split(flow, channels);
  cv::Mat magnitude, angle_deg;
  // Image y points down: negate v so that "up" on screen is +90 degrees.
  cv::cartToPolar(channels[0], -channels[1], magnitude, angle_deg, /*angleInDegrees=*/true);
  double scale = max_magnitude_px;
  if (!(scale > 0.0)) cv::minMaxLoc(magnitude, nullptr, &scale);
  cv::Mat hsv(flow.size(), CV_8UC3);
  // Float arithmetic; + 0.5 and truncation round the non-negative values half away from zero, as
  // std::lround does, at a fraction of its cost (this runs twice per frame in the live chain).
  const float value_per_px = scale > 0.0 ? static_cast<float>(255.0 / scale) : 0.0f;
  for (int y = 0; y < flow.rows; ++y) {
    const float* mag = magnitude.ptr<float>(y);
    const float* ang = angle_deg.ptr<float>(y);
    cv::Vec3b* out = hsv.ptr<cv::Vec3b>(y);
    for (int x = 0; x < flow.cols; ++x) {
      int hue = static_cast<int>(ang[x] * 0.5f + 0.5f);
      if (hue >= 180) hue -= 180;
      const float value = std::min(255.0f, mag[x] * value_per_px);
      out[x] = cv::Vec3b(static_cast<uchar>(hue), 255, static_cast<uchar>(static_cast<int>(value + 0.5f)));
    }
  }
  cv::cvtColor(hsv, rgb, cv::COLOR_HSV2RGB);
}

}  // namespace deep_ois
