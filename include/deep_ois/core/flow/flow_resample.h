// Moving a dense flow between grids: the network works on its own grid, the gyro flow and the
// images live on others.
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// Resamples a CV_32FC2 flow expressed in pixels of its own grid to a grid of `size`, expressed in
// pixels of that grid: values are resized (area averaging when shrinking, bilinear when growing;
// both keep OpenCV's pixel-centre alignment, the grid convention of the README) and u, v are scaled
// by the ratio of the widths and of the heights.
cv::Mat resampleFlow(const cv::Mat& flow, cv::Size size);

}  // namespace deep_ois
