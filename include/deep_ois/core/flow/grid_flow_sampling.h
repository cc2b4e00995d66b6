// Dense flows on the working grid (the GyroFlow message's flow, the network's input and output)
// read back in camera pixels.
//
// Grid convention (README, HomographyFlowRenderer): a grid of G pixels spans a camera image of C
// pixels per axis with s = C / G camera pixels per grid pixel; grid pixel g stands for camera
// pixel (g + 0.5) s - 0.5 (pixel centres line up), and flow values are in grid pixels, so a
// camera displacement is the grid value times s.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "deep_ois/core/flow/working_grid.h"

namespace deep_ois {

// The displacement, in camera pixels, that the CV_32FC2 grid flow gives camera pixel `p_px` of
// frame a: the grid is sampled bilinearly at g = (p + 0.5) / s - 0.5, clamped to the grid's
// border pixels (as cv::resize does), and scaled by s. Throws std::invalid_argument when the flow
// is not a non-empty CV_32FC2 or the camera size is empty.
Eigen::Vector2d sampleGridFlow(const cv::Mat& grid_flow, const cv::Size& camera_size,
                               const Eigen::Vector2d& p_px);

// The whole grid flow at camera resolution, in camera pixels (CV_32FC2 of camera_size): the same
// bilinear sampling and scaling as sampleGridFlow at every camera pixel.
cv::Mat gridFlowToCameraFlow(const cv::Mat& grid_flow, const cv::Size& camera_size);

}  // namespace deep_ois
