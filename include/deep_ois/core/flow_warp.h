// Image warping by a dense flow, for the alignment visualisations (ghost images).
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// Brings frame b into frame a's pixels: result(p) = image_b(p + flow(p)), bilinear, black where
// p + flow(p) falls outside frame b. `camera_flow` is CV_32FC2 of image_b's size, in camera
// pixels, defined at the pixels of frame a (the flow convention of deep_ois), so no inversion is
// needed and the result is exact wherever the flow is. Throws std::invalid_argument on a size or
// type mismatch.
cv::Mat warpFrameBOntoA(const cv::Mat& image_b, const cv::Mat& camera_flow);

}  // namespace deep_ois
