// Warping one frame of a pair onto the other with the pair's forward flow (a -> b): frame a onto
// frame b (the compensation nodelet's aligned image) needs the flow inverted; frame b into frame
// a's pixels (the evaluator's ghost images) does not.
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// Backward sampling map for frame b, inverted per camera pixel: the accurate reference of the
// grid-built map of backward_map.h (what the nodelet and the tools warp with), slower by the
// camera's pixel count. For every pixel q of b (camera resolution `image_size`), the
// position p in frame a with p + flow(p) = q. `flow_grid` is CV_32FC2 on any grid in that grid's
// pixels (the GyroFlow convention). The forward flow is inverted by fixed-point iteration
// p <- q - flow(p) starting at p = q - flow(q): the flow is smooth (a few homographies), so
// `iterations` = 3 brings the error well below 0.01 px for flows of tens of pixels. Returns
// CV_32FC2 in camera pixels.
cv::Mat inverseFlowMap(const cv::Mat& flow_grid, cv::Size image_size, int iterations = 3);

// `image` resampled at `inverse_map` (from inverseFlowMap), bilinear, black outside: several images
// of one pair (raw, RGB for display) share one map.
cv::Mat warpWithInverseMap(const cv::Mat& image, const cv::Mat& inverse_map);

// Frame a resampled into frame b's pixel grid (bilinear; pixels that come from outside frame a
// are black): where the flow is right, the result lines up with frame b. Builds the map on the
// flow's grid (buildFixedPointBackwardMap), as the compensation nodelet does.
cv::Mat warpOntoLaterFrame(const cv::Mat& image_a, const cv::Mat& flow_grid, int iterations = 3);

// Brings frame b into frame a's pixels: result(p) = image_b(p + flow(p)), bilinear, black where
// p + flow(p) falls outside frame b. `camera_flow` is CV_32FC2 of image_b's size, in camera
// pixels, defined at the pixels of frame a (the flow convention of deep_ois), so no inversion is
// needed and the result is exact wherever the flow is. Throws std::invalid_argument on a size or
// type mismatch.
cv::Mat warpFrameBOntoA(const cv::Mat& image_b, const cv::Mat& camera_flow);

}  // namespace deep_ois
