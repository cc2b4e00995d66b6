#include "deep_ois/core/evaluation/table_row_method.h"

#include <limits>
#include <stdexcept>

#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/flow/grid_flow_sampling.h"
#include "deep_ois/core/flow/homography_flow.h"

namespace deep_ois {

AlignmentEstimate AlignmentEstimate::failed(const std::string& reason) {
  AlignmentEstimate estimate;
  estimate.kind = Kind::kFailed;
  estimate.failure_reason = reason;
  return estimate;
}

AlignmentEstimate AlignmentEstimate::rawHomography(const Eigen::Matrix3d& H) {
  AlignmentEstimate estimate;
  estimate.kind = Kind::kHomographies;
  estimate.homographies = {H};
  estimate.undistorted_pixels = false;
  return estimate;
}

AlignmentEstimate AlignmentEstimate::patchHomographies(
    const std::vector<Eigen::Matrix3d>& homographies_undistorted) {
  AlignmentEstimate estimate;
  estimate.kind = Kind::kHomographies;
  estimate.homographies = homographies_undistorted;
  estimate.undistorted_pixels = true;
  return estimate;
}

AlignmentEstimate AlignmentEstimate::gridFlow(const cv::Mat& flow) {
  AlignmentEstimate estimate;
  estimate.kind = Kind::kGridFlow;
  estimate.grid_flow = flow;
  return estimate;
}

double estimateDistance(const AlignmentEstimate& estimate, const FramePairContext& pair) {
  if (!pair.camera) throw std::invalid_argument("estimateDistance: the pair has no camera");
  const CameraModel& camera = *pair.camera;
  switch (estimate.kind) {
    case AlignmentEstimate::Kind::kFailed:
      return std::numeric_limits<double>::quiet_NaN();
    case AlignmentEstimate::Kind::kHomographies:
      return estimate.undistorted_pixels ? geometryDistance(pair.points_a_px, pair.points_b_px,
                                                            estimate.homographies, camera)
                                         : geometryDistance(pair.points_a_px, pair.points_b_px,
                                                            estimate.homographies, camera.height());
    case AlignmentEstimate::Kind::kGridFlow:
      return geometryDistanceOfGridFlow(pair.points_a_px, pair.points_b_px, estimate.grid_flow,
                                        cv::Size(camera.width(), camera.height()));
  }
  return std::numeric_limits<double>::quiet_NaN();
}

cv::Mat estimateCameraFlow(const AlignmentEstimate& estimate, const CameraModel& camera) {
  const cv::Size camera_size(camera.width(), camera.height());
  switch (estimate.kind) {
    case AlignmentEstimate::Kind::kFailed:
      break;
    case AlignmentEstimate::Kind::kHomographies: {
      if (estimate.homographies.empty())
        throw std::invalid_argument("estimateCameraFlow: no homographies");
      // Rendered on a grid of the camera's own size (1 grid pixel = 1 camera pixel); raw-pixel
      // homographies through a distortion-free copy of the camera.
      const CameraModel model = estimate.undistorted_pixels
                                    ? camera
                                    : CameraModel(camera.width(), camera.height(), camera.K());
      const HomographyFlowRenderer renderer(model, camera_size,
                                            static_cast<int>(estimate.homographies.size()));
      cv::Mat flow;
      renderer.render(estimate.homographies, flow);
      return flow;
    }
    case AlignmentEstimate::Kind::kGridFlow:
      return gridFlowToCameraFlow(estimate.grid_flow, camera_size);
  }
  return cv::Mat(camera_size, CV_32FC2, cv::Scalar::all(0));
}

}  // namespace deep_ois
