#include "deep_ois/core/flow/working_grid.h"

#include <stdexcept>
#include <string>

namespace deep_ois {

WorkingGrid::WorkingGrid(cv::Size camera_size, cv::Size grid_size)
    : camera_size_(camera_size), grid_size_(grid_size) {
  if (camera_size.width <= 0 || camera_size.height <= 0 || grid_size.width <= 0 ||
      grid_size.height <= 0) {
    throw std::invalid_argument("WorkingGrid: camera size " + std::to_string(camera_size.width) +
                                "x" + std::to_string(camera_size.height) + " and grid size " +
                                std::to_string(grid_size.width) + "x" +
                                std::to_string(grid_size.height) + " must be positive");
  }
  scale_ = Eigen::Vector2d(static_cast<double>(camera_size.width) / grid_size.width,
                           static_cast<double>(camera_size.height) / grid_size.height);
}

}  // namespace deep_ois
