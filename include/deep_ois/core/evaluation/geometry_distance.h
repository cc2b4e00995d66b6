// The paper's alignment metric on annotated correspondences: the mean over the points of a pair
// of |p_a + flow(p_a) - p_b|, pixels of the raw image (OpenCV convention). Every motion model is
// scored through it: patch homographies (gyro, Fundamental Mixtures), one global homography
// (image baselines) and dense flows on the working grid (the compensation network).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"

namespace deep_ois {

// Mean over the annotated pairs of |H_i(p_a) p_a - p_b| in pixels, where H_i is the homography of
// the row patch that p_a's row falls in (rows [i*h/N, (i+1)*h/N)); the homographies act on the
// pixels as they are (no lens model). Empty input gives NaN.
// Throws std::invalid_argument when the point lists differ in length or there are no homographies.
double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies,
                        int image_height_px);

// The same for homographies between undistorted pixels (rotation models: gyro, Fundamental
// Mixtures): p_a moves to distort(H_i undistort(p_a)), the flow the gyro flow nodelet renders.
// Without distortion in `camera` this equals the overload above.
double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies,
                        const CameraModel& camera);

// The same for a dense CV_32FC2 flow on the working grid (grid_flow.h convention: values in grid
// pixels, sampled bilinearly at p_a's grid position and scaled to camera pixels).
// Throws std::invalid_argument on mismatched lists or an unusable flow.
double geometryDistanceOfGridFlow(const std::vector<Eigen::Vector2d>& points_a_px,
                                  const std::vector<Eigen::Vector2d>& points_b_px,
                                  const cv::Mat& grid_flow, const cv::Size& camera_size);

}  // namespace deep_ois
