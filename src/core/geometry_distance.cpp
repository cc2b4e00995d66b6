#include "deep_ois/core/geometry_distance.h"

#include <Eigen/Geometry>
#include <limits>
#include <stdexcept>

#include "deep_ois/core/rolling_shutter_homographies.h"

namespace deep_ois {

double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies, int image_height_px) {
  if (points_a_px.size() != points_b_px.size()) {
    throw std::invalid_argument("geometryDistance: point lists differ in length");
  }
  if (patch_homographies.empty()) throw std::invalid_argument("geometryDistance: no homographies");
  if (points_a_px.empty()) return std::numeric_limits<double>::quiet_NaN();
  const int patches = static_cast<int>(patch_homographies.size());
  double sum = 0.0;
  for (std::size_t k = 0; k < points_a_px.size(); ++k) {
    const Eigen::Vector2d& p = points_a_px[k];
    const Eigen::Matrix3d& H = patch_homographies[patchIndexOfRow(p.y(), image_height_px, patches)];
    sum += ((H * p.homogeneous()).hnormalized() - points_b_px[k]).norm();
  }
  return sum / static_cast<double>(points_a_px.size());
}

}  // namespace deep_ois
