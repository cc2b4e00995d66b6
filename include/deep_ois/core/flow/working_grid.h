// The working grid: the fixed-size grid on which flows travel (the GyroFlow message's flow, the
// network's input and output), and its one mapping to and from camera pixels.
//
// A grid of G pixels per axis spans a camera image of C pixels, s = C / G camera pixels per grid
// pixel. Grid pixel g stands for camera pixel (g + 0.5) s - 0.5: pixel centres line up, which is
// also the convention of cv::resize, so a grid flow resized to camera size samples exactly here.
// Flow values on the grid are in grid pixels: a camera displacement is the grid value times s.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace deep_ois {

class WorkingGrid {
 public:
  // Throws std::invalid_argument when either size is not positive.
  WorkingGrid(cv::Size camera_size, cv::Size grid_size);

  cv::Size cameraSize() const { return camera_size_; }
  cv::Size gridSize() const { return grid_size_; }
  // Camera pixels per grid pixel along x and y.
  const Eigen::Vector2d& scale() const { return scale_; }

  // The camera pixel that grid pixel g stands for: (g + 0.5) s - 0.5.
  Eigen::Vector2d toCamera(const Eigen::Vector2d& g) const {
    return ((g.array() + 0.5) * scale_.array() - 0.5).matrix();
  }
  // The grid position of camera pixel p_px (not clamped): (p + 0.5) / s - 0.5.
  Eigen::Vector2d toGrid(const Eigen::Vector2d& p_px) const {
    return ((p_px.array() + 0.5) / scale_.array() - 0.5).matrix();
  }

 private:
  cv::Size camera_size_;
  cv::Size grid_size_;
  Eigen::Vector2d scale_;
};

}  // namespace deep_ois
