#include "deep_ois/core/flow/flow_warp.h"

#include <opencv2/imgproc.hpp>

#include <stdexcept>

#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/grid_flow_sampling.h"

namespace deep_ois {

cv::Mat inverseFlowMap(const cv::Mat& flow_grid, cv::Size image_size, int iterations) {
  if (flow_grid.type() != CV_32FC2 || flow_grid.empty()) {
    throw std::invalid_argument("inverseFlowMap: the flow must be a non-empty CV_32FC2 image");
  }
  if (iterations < 0) throw std::invalid_argument("inverseFlowMap: iterations must be >= 0");
  // The flow in camera pixels at every camera pixel (the evaluator's grid sampling).
  const cv::Mat flow = gridFlowToCameraFlow(flow_grid, image_size);
  cv::Mat identity(image_size, CV_32FC2);
  identity.forEach<cv::Vec2f>([](cv::Vec2f& value, const int* position) {
    value = cv::Vec2f(static_cast<float>(position[1]), static_cast<float>(position[0]));
  });
  cv::Mat map = identity - flow;
  cv::Mat flow_at_map;
  for (int i = 0; i < iterations; ++i) {
    // Edge replication: near the border p may leave the image, where the smooth flow continues.
    cv::remap(flow, flow_at_map, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    map = identity - flow_at_map;
  }
  return map;
}

cv::Mat warpWithInverseMap(const cv::Mat& image, const cv::Mat& inverse_map) {
  if (image.empty() || image.size() != inverse_map.size() || inverse_map.type() != CV_32FC2) {
    throw std::invalid_argument("warpWithInverseMap: the image and the CV_32FC2 map must have one size");
  }
  cv::Mat warped;
  cv::remap(image, warped, inverse_map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return warped;
}

cv::Mat warpOntoLaterFrame(const cv::Mat& image_a, const cv::Mat& flow_grid, int iterations) {
  if (image_a.empty()) throw std::invalid_argument("warpOntoLaterFrame: frame a is empty");
  FixedPointMap map;
  buildFixedPointBackwardMap(flow_grid, image_a.size(), iterations, map);
  cv::Mat warped;
  warpWithFixedPointMap(image_a, map, warped);
  return warped;
}

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
