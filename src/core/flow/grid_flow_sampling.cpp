#include "deep_ois/core/flow/grid_flow_sampling.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace deep_ois {
namespace {

void checkGridFlow(const cv::Mat& grid_flow, const cv::Size& camera_size, const char* caller) {
  if (grid_flow.empty() || grid_flow.type() != CV_32FC2) {
    throw std::invalid_argument(std::string(caller) +
                                ": the grid flow must be a non-empty CV_32FC2");
  }
  if (camera_size.width <= 0 || camera_size.height <= 0) {
    throw std::invalid_argument(std::string(caller) + ": the camera size must be positive");
  }
}

}  // namespace

Eigen::Vector2d sampleGridFlow(const cv::Mat& grid_flow, const cv::Size& camera_size,
                               const Eigen::Vector2d& p_px) {
  checkGridFlow(grid_flow, camera_size, "sampleGridFlow");
  const WorkingGrid grid(camera_size, grid_flow.size());
  const Eigen::Vector2d& s = grid.scale();
  // Grid coordinates of the camera pixel, clamped so that the border pixels extend outwards.
  const Eigen::Vector2d g = grid.toGrid(p_px);
  const double gx = std::clamp(g.x(), 0.0, grid_flow.cols - 1.0);
  const double gy = std::clamp(g.y(), 0.0, grid_flow.rows - 1.0);
  const int x0 = static_cast<int>(std::floor(gx)), y0 = static_cast<int>(std::floor(gy));
  const int x1 = std::min(x0 + 1, grid_flow.cols - 1), y1 = std::min(y0 + 1, grid_flow.rows - 1);
  const double fx = gx - x0, fy = gy - y0;
  const cv::Vec2f& f00 = grid_flow.at<cv::Vec2f>(y0, x0);
  const cv::Vec2f& f01 = grid_flow.at<cv::Vec2f>(y0, x1);
  const cv::Vec2f& f10 = grid_flow.at<cv::Vec2f>(y1, x0);
  const cv::Vec2f& f11 = grid_flow.at<cv::Vec2f>(y1, x1);
  Eigen::Vector2d grid_value;
  for (int c = 0; c < 2; ++c) {
    grid_value[c] =
        (1 - fy) * ((1 - fx) * f00[c] + fx * f01[c]) + fy * ((1 - fx) * f10[c] + fx * f11[c]);
  }
  return grid_value.cwiseProduct(s);
}

cv::Mat gridFlowToCameraFlow(const cv::Mat& grid_flow, const cv::Size& camera_size) {
  checkGridFlow(grid_flow, camera_size, "gridFlowToCameraFlow");
  const Eigen::Vector2d s = WorkingGrid(camera_size, grid_flow.size()).scale();
  // cv::resize's bilinear mode maps destination pixel p to source (p + 0.5) / s - 0.5 and
  // replicates the border: exactly the working grid's convention.
  cv::Mat camera_flow;
  if (grid_flow.size() == camera_size) {
    camera_flow = grid_flow.clone();
  } else {
    cv::resize(grid_flow, camera_flow, camera_size, 0.0, 0.0, cv::INTER_LINEAR);
  }
  cv::multiply(camera_flow, cv::Scalar(s.x(), s.y()), camera_flow);
  return camera_flow;
}

}  // namespace deep_ois
