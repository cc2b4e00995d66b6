#include "deep_ois/core/flow/homography_flow.h"

#include <sstream>
#include <stdexcept>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {

HomographyFlowRenderer::HomographyFlowRenderer(const CameraModel& camera, cv::Size grid_size,
                                               int patch_count)
    : camera_(camera),
      grid_(cv::Size(camera.width(), camera.height()), grid_size),
      patch_count_(patch_count) {
  const std::string camera_problem = camera.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("HomographyFlowRenderer: " + camera_problem);
  if (grid_size.width <= 0 || grid_size.height <= 0) {
    throw std::invalid_argument("HomographyFlowRenderer: grid size must be positive");
  }
  if (patch_count < 1) throw std::invalid_argument("HomographyFlowRenderer: patch_count must be >= 1");
  const std::size_t count = static_cast<std::size_t>(grid_size.area());
  raw_px_.resize(count);
  undistorted_px_.resize(count);
  patch_of_grid_row_.resize(grid_size.height);
  for (int gy = 0; gy < grid_size.height; ++gy) {
    patch_of_grid_row_[gy] = patchIndexOfRow(gridToCamera(0, gy).y(), camera.height(), patch_count);
    for (int gx = 0; gx < grid_size.width; ++gx) {
      const std::size_t k = static_cast<std::size_t>(gy) * grid_size.width + gx;
      raw_px_[k] = gridToCamera(gx, gy);
    }
  }
  undistorted_px_ = raw_px_;
  camera.undistortPoints(undistorted_px_);  // one OpenCV call for the whole grid
}

Eigen::Vector2d HomographyFlowRenderer::gridToCamera(double gx, double gy) const {
  return grid_.toCamera(Eigen::Vector2d(gx, gy));
}

void HomographyFlowRenderer::render(const std::vector<Eigen::Matrix3d>& homographies,
                                    cv::Mat& flow) const {
  if (static_cast<int>(homographies.size()) != patch_count_) {
    std::ostringstream why;
    why << "HomographyFlowRenderer::render: got " << homographies.size() << " homographies for "
        << patch_count_ << " patches";
    throw std::invalid_argument(why.str());
  }
  flow.create(grid_.gridSize(), CV_32FC2);
  const double inv_sx = 1.0 / grid_.scale().x(), inv_sy = 1.0 / grid_.scale().y();
  // H_i applied to every undistorted grid point, then distorted back in one OpenCV call.
  std::vector<Eigen::Vector2d> mapped(undistorted_px_.size());
  for (int gy = 0; gy < grid_.gridSize().height; ++gy) {
    const Eigen::Matrix3d& H = homographies[patch_of_grid_row_[gy]];
    const std::size_t row_start = static_cast<std::size_t>(gy) * grid_.gridSize().width;
    for (int gx = 0; gx < grid_.gridSize().width; ++gx) {
      const Eigen::Vector2d& q = undistorted_px_[row_start + gx];
      const double w = H(2, 0) * q.x() + H(2, 1) * q.y() + H(2, 2);
      mapped[row_start + gx] = Eigen::Vector2d((H(0, 0) * q.x() + H(0, 1) * q.y() + H(0, 2)) / w,
                                               (H(1, 0) * q.x() + H(1, 1) * q.y() + H(1, 2)) / w);
    }
  }
  camera_.distortPoints(mapped);
  for (int gy = 0; gy < grid_.gridSize().height; ++gy) {
    cv::Vec2f* out = flow.ptr<cv::Vec2f>(gy);
    const std::size_t row_start = static_cast<std::size_t>(gy) * grid_.gridSize().width;
    for (int gx = 0; gx < grid_.gridSize().width; ++gx) {
      const Eigen::Vector2d& p = raw_px_[row_start + gx];
      const Eigen::Vector2d& m = mapped[row_start + gx];
      out[gx] = cv::Vec2f(static_cast<float>((m.x() - p.x()) * inv_sx),
                          static_cast<float>((m.y() - p.y()) * inv_sy));
    }
  }
}

}  // namespace deep_ois
