#include "deep_ois/core/flow_warp.h"

#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace deep_ois {

cv::Mat warpFrameBOntoA(const cv::Mat& image_b, const cv::Mat& camera_flow) {
  if (image_b.empty() || camera_flow.type() != CV_32FC2 || camera_flow.size() != image_b.size()) {
    throw std::invalid_argument(
        "warpFrameBOntoA: need a non-empty image and a CV_32FC2 flow of the same size");
  }
  cv::Mat map(camera_flow.size(), CV_32FC2);
  for (int y = 0; y < map.rows; ++y) {
    const cv::Vec2f* flow = camera_flow.ptr<cv::Vec2f>(y);
    cv::Vec2f* out = map.ptr<cv::Vec2f>(y);
    for (int x = 0; x < map.cols; ++x) out[x] = cv::Vec2f(x + flow[x][0], y + flow[x][1]);
  }
  cv::Mat warped;
  cv::remap(image_b, warped, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar::all(0));
  return warped;
}

}  // namespace deep_ois
