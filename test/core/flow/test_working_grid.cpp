#include <gtest/gtest.h>

#include <stdexcept>

#include "deep_ois/core/flow/working_grid.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

TEST(WorkingGrid, PixelCentresLineUp) {
  const WorkingGrid grid(cv::Size(800, 600), cv::Size(400, 300));
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(2.0, 2.0), grid.scale(), 0.0);
  // Grid pixel 0 covers camera pixels 0 and 1: its centre is at 0.5.
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(0.5, 0.5), grid.toCamera(Eigen::Vector2d(0, 0)), 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(798.5, 598.5), grid.toCamera(Eigen::Vector2d(399, 299)),
                     1e-12);
}

TEST(WorkingGrid, ToGridInvertsToCamera) {
  const WorkingGrid grid(cv::Size(1280, 720), cv::Size(360, 270));
  for (const Eigen::Vector2d& g : {Eigen::Vector2d(0, 0), Eigen::Vector2d(17.25, 101.5),
                                  Eigen::Vector2d(359, 269), Eigen::Vector2d(-3, 400)}) {
    EXPECT_MATRIX_NEAR(g, grid.toGrid(grid.toCamera(g)), 1e-12);
  }
}

TEST(WorkingGrid, RefusesEmptySizes) {
  EXPECT_THROW(WorkingGrid(cv::Size(0, 480), cv::Size(360, 270)), std::invalid_argument);
  EXPECT_THROW(WorkingGrid(cv::Size(640, 480), cv::Size(360, 0)), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
