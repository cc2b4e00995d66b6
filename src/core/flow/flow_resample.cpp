#include "deep_ois/core/flow/flow_resample.h"

#include <opencv2/imgproc.hpp>

#include <stdexcept>

namespace deep_ois {

cv::Mat resampleFlow(const cv::Mat& flow, cv::Size size) {
  if (flow.type() != CV_32FC2 || flow.empty()) throw std::invalid_argument("resampleFlow: flow must be a non-empty CV_32FC2");
  if (size.width < 1 || size.height < 1) throw std::invalid_argument("resampleFlow: target size must be positive");
  if (size == flow.size()) return flow.clone();
  cv::Mat resized;
  const bool shrinking = size.width < flow.cols && size.height < flow.rows;
  cv::resize(flow, resized, size, 0, 0, shrinking ? cv::INTER_AREA : cv::INTER_LINEAR);
  const float scale_u = static_cast<float>(size.width) / static_cast<float>(flow.cols);
  const float scale_v = static_cast<float>(size.height) / static_cast<float>(flow.rows);
  resized.forEach<cv::Vec2f>([&](cv::Vec2f& value, const int*) {
    value[0] *= scale_u;
    value[1] *= scale_v;
  });
  return resized;
}

}  // namespace deep_ois
