// Dense flow on a fixed working grid from a rolling-shutter homography array.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/flow/working_grid.h"

namespace deep_ois {

// Renders flow(p) = H_i(p) p - p (or distort(H_i undistort(p)) - p with lens distortion) on a
// working grid of `grid_size` pixels that spans the whole camera image (working_grid.h: grid pixel
// g stands for camera pixel (g + 0.5) s - 0.5), in grid pixels: (u, v) = camera displacement / s.
//
// The per-pixel undistortion and patch lookup are precomputed once per camera and grid (they
// are the costly part with distortion), so render() is a homography and a distortion per pixel.
class HomographyFlowRenderer {
 public:
  HomographyFlowRenderer(const CameraModel& camera, cv::Size grid_size, int patch_count);

  // `homographies` must have patch_count entries, each mapping undistorted camera pixels of frame
  // a to frame b. Writes a CV_32FC2 grid (reallocated only when its size or type differs).
  void render(const std::vector<Eigen::Matrix3d>& homographies, cv::Mat& flow) const;

  // Camera pixel that grid pixel (gx, gy) stands for.
  Eigen::Vector2d gridToCamera(double gx, double gy) const;
  // Camera pixels per grid pixel along x and y.
  Eigen::Vector2d scale() const { return grid_.scale(); }

  bool compatible(const CameraModel& camera, cv::Size grid_size, int patch_count) const {
    return camera == camera_ && grid_size == grid_.gridSize() && patch_count == patch_count_;
  }
  const CameraModel& camera() const { return camera_; }
  cv::Size gridSize() const { return grid_.gridSize(); }
  int patchCount() const { return patch_count_; }

 private:
  CameraModel camera_;
  WorkingGrid grid_;
  int patch_count_;
  std::vector<Eigen::Vector2d> raw_px_;          // camera pixel per grid pixel, row-major
  std::vector<Eigen::Vector2d> undistorted_px_;  // its undistorted position
  std::vector<int> patch_of_grid_row_;           // patch index per grid row
};

}  // namespace deep_ois
