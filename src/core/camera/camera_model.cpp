#include "deep_ois/core/camera/camera_model.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <sstream>

namespace deep_ois {

namespace {

// OpenCV's iterative undistortion stops when a step is below this (normalised coordinates, i.e.
// ~1e-9 px at a focal length of 1000 px) or after this many iterations.
const cv::TermCriteria kUndistortCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12);

std::vector<cv::Point2d> normalised(const std::vector<Eigen::Vector2d>& px, const Eigen::Matrix3d& K_inv) {
  std::vector<cv::Point2d> xy(px.size());
  for (std::size_t i = 0; i < px.size(); ++i) {
    const Eigen::Vector2d n = (K_inv * px[i].homogeneous()).hnormalized();
    xy[i] = cv::Point2d(n.x(), n.y());
  }
  return xy;
}

void toPixels(const std::vector<cv::Point2d>& xy, const Eigen::Matrix3d& K, std::vector<Eigen::Vector2d>& px) {
  for (std::size_t i = 0; i < xy.size(); ++i) px[i] = (K * Eigen::Vector3d(xy[i].x, xy[i].y, 1.0)).hnormalized();
}

}  // namespace

const char* distortionModelName(DistortionModel model) {
  switch (model) {
    case DistortionModel::kPlumbBob: return "plumb_bob";
    case DistortionModel::kRationalPolynomial: return "rational_polynomial";
    case DistortionModel::kEquidistant: return "equidistant";
  }
  return "unknown";
}

std::size_t distortionCoefficientCount(DistortionModel model) {
  switch (model) {
    case DistortionModel::kPlumbBob: return 5;
    case DistortionModel::kRationalPolynomial: return 8;
    case DistortionModel::kEquidistant: return 4;
  }
  return 0;
}

CameraModel::CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K,
                         const std::vector<double>& plumb_bob)
    : CameraModel(width_px, height_px, K, DistortionModel::kPlumbBob, plumb_bob) {}

CameraModel::CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K, DistortionModel model,
                         const std::vector<double>& coefficients)
    : width_px_(width_px), height_px_(height_px), K_(K), model_(model), coefficients_(coefficients) {
  if (coefficients_.size() < distortionCoefficientCount(model)) coefficients_.resize(distortionCoefficientCount(model), 0.0);
  for (double c : coefficients_) has_distortion_ = has_distortion_ || c != 0.0;
  if (model == DistortionModel::kPlumbBob) {
    for (std::size_t i = 0; i < 5; ++i) plumb_bob_[i] = coefficients_[i];
  }
  if (K_.allFinite() && std::abs(K_.determinant()) > 0.0) K_inv_ = K_.inverse();
}

std::string CameraModel::validate() const {
  std::ostringstream why;
  bool finite = K_.allFinite();
  for (double c : coefficients_) finite = finite && std::isfinite(c);
  if (width_px_ <= 0 || height_px_ <= 0) {
    why << "image size " << width_px_ << "x" << height_px_ << " is not positive";
  } else if (!finite) {
    why << "intrinsics or distortion contain non-finite values";
  } else if (!(K_(0, 0) > 0.0) || !(K_(1, 1) > 0.0)) {
    why << "focal lengths fx=" << K_(0, 0) << ", fy=" << K_(1, 1) << " must be positive";
  } else if (K_(1, 0) != 0.0 || K_(2, 0) != 0.0 || K_(2, 1) != 0.0 || K_(2, 2) != 1.0) {
    why << "intrinsic matrix K must be upper triangular with K[2][2] = 1";
  } else if (coefficients_.size() > distortionCoefficientCount(model_)) {
    why << distortionModelName(model_) << " distortion has " << coefficients_.size()
        << " coefficients, expected at most " << distortionCoefficientCount(model_);
  }
  return why.str();
}

void CameraModel::distortPoints(std::vector<Eigen::Vector2d>& px) const {
  if (!has_distortion_ || px.empty()) return;
  const std::vector<cv::Point2d> xy = normalised(px, K_inv_);
  std::vector<cv::Point2d> distorted;
  const cv::Matx33d identity = cv::Matx33d::eye();
  if (model_ == DistortionModel::kEquidistant) {
    cv::fisheye::distortPoints(xy, distorted, identity, coefficients_);
  } else {
    std::vector<cv::Point3d> rays(xy.size());
    for (std::size_t i = 0; i < xy.size(); ++i) rays[i] = cv::Point3d(xy[i].x, xy[i].y, 1.0);
    cv::projectPoints(rays, cv::Vec3d::all(0.0), cv::Vec3d::all(0.0), identity, coefficients_, distorted);
  }
  toPixels(distorted, K_, px);
}

void CameraModel::undistortPoints(std::vector<Eigen::Vector2d>& px) const {
  if (!has_distortion_ || px.empty()) return;
  const std::vector<cv::Point2d> xy = normalised(px, K_inv_);
  std::vector<cv::Point2d> undistorted;
  const cv::Matx33d identity = cv::Matx33d::eye();
  if (model_ == DistortionModel::kEquidistant) {
    cv::fisheye::undistortPoints(xy, undistorted, identity, coefficients_, cv::noArray(), identity,
                                 kUndistortCriteria);
  } else {
    cv::undistortPoints(xy, undistorted, identity, coefficients_, cv::noArray(), identity, kUndistortCriteria);
  }
  toPixels(undistorted, K_, px);
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& undistorted_px) const {
  if (!has_distortion_) return undistorted_px;
  std::vector<Eigen::Vector2d> px{undistorted_px};
  distortPoints(px);
  return px[0];
}

Eigen::Vector2d CameraModel::undistort(const Eigen::Vector2d& distorted_px) const {
  if (!has_distortion_) return distorted_px;
  std::vector<Eigen::Vector2d> px{distorted_px};
  undistortPoints(px);
  return px[0];
}

bool CameraModel::operator==(const CameraModel& other) const {
  return width_px_ == other.width_px_ && height_px_ == other.height_px_ && K_ == other.K_ &&
         model_ == other.model_ && coefficients_ == other.coefficients_;
}

}  // namespace deep_ois
