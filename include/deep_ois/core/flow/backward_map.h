// The backward sampling map that warps frame a onto frame b, built where the motion lives: the
// forward flow a -> b is inverted on its working grid (a few hundred thousand points at most,
// whatever the camera), and only the bilinear interpolation of that inverse to camera pixels runs
// per camera pixel, written straight into the fixed-point form cv::remap consumes. The per-frame
// cost at camera resolution is then one interpolation pass plus one remap.
//
// Accuracy: inverseFlowMap (flow_warp.h) inverts per camera pixel and stays the reference;
// test_backward_map checks that this map stays within 0.01 px of it on the sample bag's flows and
// on a strong rotation at 1920x1080.
#pragma once

#include <opencv2/core.hpp>

#include <memory>

namespace deep_ois {

struct BackwardMapScratch;  // a build's working buffers (backward_map.cpp)

// A backward map in cv::remap's fixed-point form (what cv::convertMaps gives for CV_16SC2):
// `xy` CV_16SC2 holds floor(position) and `fraction` CV_16UC1 the 1/32-pixel fractions
// (row * 32 + column of cv::remap's interpolation table). cv::remap with a CV_32FC2 map rounds
// to the same 1/32 pixel internally, so the result is the same, without the conversion per frame.
// The buffers are reused from frame to frame while the camera size stays the same.
struct FixedPointMap {
  cv::Mat xy;        // CV_16SC2
  cv::Mat fraction;  // CV_16UC1
  // Camera pixels inverted one by one (near kinks of the flow) rather than interpolated.
  std::size_t pixels_inverted_one_by_one = 0;
  // The build's working buffers at grid resolution, kept from frame to frame like xy and fraction.
  std::shared_ptr<BackwardMapScratch> scratch;
  cv::Size size() const { return xy.size(); }
};

// The inverse of the forward flow at the nodes of its own grid: for each grid pixel g, standing for
// camera pixel q = (g + 0.5) s - 0.5 of frame b (working_grid.h), the displacement d in camera
// pixels with p = q + d and p + flow(p) = q, found by the fixed-point iteration p <- q - flow(p)
// from p = q - flow(q) (as inverseFlowMap, with the flow sampled bilinearly on the grid, border
// pixels replicated; all steps but the last through cv::remap, i.e. at 1/32 grid pixel, the last
// one exact, which shrinks that rounding's effect by the flow gradient). `flow_grid` is CV_32FC2 in grid pixels; returns CV_32FC2 of the grid's size
// in camera pixels. Throws std::invalid_argument on an empty or non-CV_32FC2 flow, an empty
// camera size or negative iterations.
cv::Mat inverseDisplacementOnGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations = 3);

// The backward map at camera resolution from the grid inverse (inverseDisplacementOnGrid): camera
// pixel q samples frame a at q + d(q), d interpolated bilinearly between grid nodes with the
// working grid's pixel-centre convention (continued linearly past the outermost nodes). Where the
// flow has a kink that interpolation would smooth over (a patch seam, the border past which the
// flow is held constant), the pixels are inverted one by one exactly as inverseFlowMap does; a
// camera no larger than the grid is inverted per pixel throughout (it has fewer pixels than the
// grid has nodes). CV_32FC2 in camera pixels: the accurate form, for tests and tools that need the
// positions themselves.
cv::Mat backwardMapFromGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations = 3);

// The same map in cv::remap's fixed-point form, written into `map` (buffers reused). The rows are
// built in cv::parallel_for_ stripes: one thread unless cv::setNumThreads allows more.
void buildFixedPointBackwardMap(const cv::Mat& flow_grid, cv::Size image_size, int iterations,
                                FixedPointMap& map);

// One row of backward positions (x, y interleaved, camera pixels) into cv::remap's fixed-point form
// with cv::convertMaps' rounding: `xy` gets 2 * width shorts, `fraction` width table indices. For
// the map builders (grid flows and patch homographies).
void writeFixedPointRow(const float* map_xy, int width, short* xy, ushort* fraction);

// `image` resampled at `map`, bilinear, black outside frame a, into `warped`: a caller that
// allocated `warped` with the image's size and type (e.g. over an outgoing message's buffer)
// gets the result there, without a copy. Throws std::invalid_argument when the sizes differ.
void warpWithFixedPointMap(const cv::Mat& image, const FixedPointMap& map, cv::Mat& warped);

}  // namespace deep_ois
