#include "deep_ois/core/evaluation/geometry_distance.h"

#include <Eigen/Geometry>
#include <limits>
#include <stdexcept>

#include "deep_ois/core/flow/grid_flow_sampling.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {
namespace {

// Mean of |moved(p_a) - p_b| after the common checks; `moved` gives where p_a lands in frame b.
template <typename Move>
double meanEndpointDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                            const std::vector<Eigen::Vector2d>& points_b_px, const Move& moved) {
  if (points_a_px.size() != points_b_px.size()) {
    throw std::invalid_argument("geometryDistance: point lists differ in length");
  }
  if (points_a_px.empty()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0.0;
  for (std::size_t k = 0; k < points_a_px.size(); ++k)
    sum += (moved(points_a_px[k]) - points_b_px[k]).norm();
  return sum / static_cast<double>(points_a_px.size());
}

}  // namespace

double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies,
                        int image_height_px) {
  if (patch_homographies.empty()) throw std::invalid_argument("geometryDistance: no homographies");
  const int patches = static_cast<int>(patch_homographies.size());
  return meanEndpointDistance(points_a_px, points_b_px, [&](const Eigen::Vector2d& p) {
    const Eigen::Matrix3d& H = patch_homographies[patchIndexOfRow(p.y(), image_height_px, patches)];
    return Eigen::Vector2d((H * p.homogeneous()).hnormalized());
  });
}

double geometryDistance(const std::vector<Eigen::Vector2d>& points_a_px,
                        const std::vector<Eigen::Vector2d>& points_b_px,
                        const std::vector<Eigen::Matrix3d>& patch_homographies,
                        const CameraModel& camera) {
  if (!camera.hasDistortion())
    return geometryDistance(points_a_px, points_b_px, patch_homographies, camera.height());
  if (patch_homographies.empty()) throw std::invalid_argument("geometryDistance: no homographies");
  const int patches = static_cast<int>(patch_homographies.size());
  return meanEndpointDistance(points_a_px, points_b_px, [&](const Eigen::Vector2d& p) {
    // The patch is chosen by the raw row, as the gyro flow does.
    const Eigen::Matrix3d& H = patch_homographies[patchIndexOfRow(p.y(), camera.height(), patches)];
    return camera.distort((H * camera.undistort(p).homogeneous()).hnormalized());
  });
}

double geometryDistanceOfGridFlow(const std::vector<Eigen::Vector2d>& points_a_px,
                                  const std::vector<Eigen::Vector2d>& points_b_px,
                                  const cv::Mat& grid_flow, const cv::Size& camera_size) {
  return meanEndpointDistance(points_a_px, points_b_px, [&](const Eigen::Vector2d& p) {
    return Eigen::Vector2d(p + sampleGridFlow(grid_flow, camera_size, p));
  });
}

}  // namespace deep_ois
