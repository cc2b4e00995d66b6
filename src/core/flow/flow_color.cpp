#include "deep_ois/core/flow/flow_color.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace deep_ois {
namespace {

// OpenCV's 8-bit hue range (degrees / 2) and the value range.
constexpr int kHues = 180;
constexpr int kValues = 256;

// Every colour the coding uses, at full saturation, computed once by cv::cvtColor itself (without
// a colour conversion per pixel and frame): index hue * 256 + value.
const std::vector<cv::Vec3b>& hueValueToRgb() {
  static const std::vector<cv::Vec3b> table = [] {
    // One pixel per row: OpenCV's scalar conversion, which a single pixel gets (its vectorised
    // rows round some colours one step lower, e.g. cyan to (0, 254, 255)).
    cv::Mat hsv(kHues * kValues, 1, CV_8UC3);
    for (int hue = 0; hue < kHues; ++hue) {
      for (int value = 0; value < kValues; ++value) {
        hsv.at<cv::Vec3b>(hue * kValues + value, 0) =
            cv::Vec3b(static_cast<uchar>(hue), 255, static_cast<uchar>(value));
      }
    }
    cv::Mat rgb;
    cv::cvtColor(hsv, rgb, cv::COLOR_HSV2RGB);
    return std::vector<cv::Vec3b>(rgb.begin<cv::Vec3b>(), rgb.end<cv::Vec3b>());
  }();
  return table;
}

}  // namespace

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
  const std::vector<cv::Vec3b>& rgb_of = hueValueToRgb();
  // Row by row through small buffers: whole-image temporaries of a few hundred kB would each be a
  // fresh mmap (and its page faults) per frame under glibc's allocator when nothing larger was
  // freed before (a small camera), several ms per frame.
  std::vector<float> u(flow.cols), v(flow.cols), magnitude(flow.cols), angle_deg(flow.cols);
  std::vector<int> index(flow.cols);
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
    // The table index per pixel, in float arithmetic the compiler vectorises; the comparisons are
    // written so that a NaN flow lands on a valid entry (hue 0, full value) instead of outside.
    for (int x = 0; x < flow.cols; ++x) {
      float hue = angle_deg[x] * 0.5f + 0.5f;
      hue = hue >= kHues ? hue - kHues : hue;
      hue = std::min(static_cast<float>(kHues - 1), std::max(0.0f, hue));
      const float value = std::max(0.0f, std::min(255.0f, magnitude[x] * value_per_px) + 0.5f);
      index[x] = static_cast<int>(hue) * kValues + static_cast<int>(value);
    }
    cv::Vec3b* out = rgb.ptr<cv::Vec3b>(y);
    for (int x = 0; x < flow.cols; ++x) out[x] = rgb_of[index[x]];
  }
}

}  // namespace deep_ois
