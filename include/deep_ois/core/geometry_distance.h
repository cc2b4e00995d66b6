// The paper's alignment metric on annotated correspondences.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace deep_ois {

// Mean over the annotated pairs of |H_i(p_a) p_a - p_b| in pixels, where H_i is the homography of
// the row patch that p_a's row falls in (rows [i*h/N, (i+1)*h/N)). Empty input gives NaN.
// Throws std::invalid_argument when the point lists differ in length or there are no homographies.
double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies, int image_height_px);

}  // namespace deep_ois
