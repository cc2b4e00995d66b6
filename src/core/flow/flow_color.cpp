#include "deep_ois/core/flow/flow_color.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace deep_ois {

cv::Mat colorizeFlow(const cv::Mat& flow, double max_magnitude_px) {
  cv::Mat rgb;
  colorizeFlow(flow, max_magnitude_px, rgb);
  return rgb;
}

void colorizeFlow(const cv::Mat& flow, double max_magnitude_px, cv::Mat& rgb) {
  if (flow.type() != CV_32FC2) throw std::invalid_argument("colorizeFlow: flow must be CV_32FC2");
  double scale = max_magnitude_px;
  if (!(scale > 0.0)) {
    double largest_squared = 0.0;
    for (int y = 0; y < flow.rows; ++y) {
      const cv::Vec2f* f = flow.ptr<cv::Vec2f>(y);
      for (int x = 0; x < flow.cols; ++x) {
        largest_squared = std::max(largest_squared, static_cast<double>(f[x][0] * f[x][0] + f[x][1] * f[x][1]));
      }
    }
    scale = std::sqrt(largest_squared);
  }
  rgb.create(flow.size(), CV_8UC3);
  // Row by row through small buffers: whole-image temporaries of a few hundred kB would each be a
  // fresh mmap (and its page faults) per frame under glibc's allocator when nothing larger was
  // freed before (a small camera), several ms per frame.
  std::vector<float> u(flow.cols), v(flow.cols), magnitude(flow.cols), angle_deg(flow.cols);
  cv::Mat hsv(1, flow.cols, CV_8UC3);
  // Float arithmetic; + 0.5 and truncation round the non-negative values half away from zero, as
  // std::lround does, at a fraction of its cost (this runs twice per frame in the live chain).
  const float value_per_px = scale > 0.0 ? static_cast<float>(255.0 / scale) : 0.0f;
  for (int y = 0; y < flow.rows; ++y) {
    const cv::Vec2f* f = flow.ptr<cv::Vec2f>(y);
    // Image y points down: negate v so that "up" on screen is +90 degrees.
    for (int x = 0; x < flow.cols; ++x) {
      u[x] = f[x][0];
      v[x] = -f[x][1];
    }
    cv::Mat magnitude_row(1, flow.cols, CV_32F, magnitude.data()), angle_row(1, flow.cols, CV_32F, angle_deg.data());
    cv::cartToPolar(cv::Mat(1, flow.cols, CV_32F, u.data()), cv::Mat(1, flow.cols, CV_32F, v.data()), magnitude_row,
                    angle_row, /*angleInDegrees=*/true);
    cv::Vec3b* out = hsv.ptr<cv::Vec3b>(0);
    for (int x = 0; x < flow.cols; ++x) {
      int hue = static_cast<int>(angle_deg[x] * 0.5f + 0.5f);
      if (hue >= 180) hue -= 180;
      const float value = std::min(255.0f, magnitude[x] * value_per_px);
      out[x] = cv::Vec3b(static_cast<uchar>(hue), 255, static_cast<uchar>(static_cast<int>(value + 0.5f)));
    }
    cv::Mat rgb_row = rgb.row(y);
    cv::cvtColor(hsv, rgb_row, cv::COLOR_HSV2RGB);
  }
}

}  // namespace deep_ois
