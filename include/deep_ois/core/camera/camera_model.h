// Pinhole camera with the lens distortion models of sensor_msgs/CameraInfo (plumb_bob,
// rational_polynomial, equidistant), computed by OpenCV's own functions.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace deep_ois {

// CameraInfo's distortion_model values, and how OpenCV computes each:
//   kPlumbBob           D = k1 k2 p1 p2 k3               cv::projectPoints / cv::undistortPoints
//   kRationalPolynomial D = k1 k2 p1 p2 k3 k4 k5 k6      cv::projectPoints / cv::undistortPoints
//   kEquidistant        D = k1 k2 k3 k4 (fisheye)        cv::fisheye::distortPoints / undistortPoints
enum class DistortionModel { kPlumbBob, kRationalPolynomial, kEquidistant };

// "plumb_bob", "rational_polynomial", "equidistant".
const char* distortionModelName(DistortionModel model);
// Number of coefficients of the model (5, 8, 4).
std::size_t distortionCoefficientCount(DistortionModel model);

// Pixel convention everywhere in deep_ois: OpenCV's, x right, y down, (0, 0) = centre of the
// top-left pixel. `K` maps normalised camera coordinates (x/z, y/z) of the optical frame to
// undistorted pixels; distortion, when present, moves undistorted pixels to the raw image. The
// distortion acts on normalised coordinates, so a skew in K is kept exactly (OpenCV's functions
// are called with an identity camera matrix and K is applied here).
class CameraModel {
 public:
  CameraModel() = default;
  // `plumb_bob` holds k1, k2, p1, p2, k3 (CameraInfo's D); fewer entries are zero-padded, an empty
  // vector means no distortion.
  CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K,
              const std::vector<double>& plumb_bob = {});
  // Any model; fewer coefficients than the model has are zero-padded, more are kept so that
  // validate() can name the problem.
  CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K, DistortionModel model,
              const std::vector<double>& coefficients);

  // Empty when the model is usable; otherwise a sentence naming what is wrong.
  std::string validate() const;

  int width() const { return width_px_; }
  int height() const { return height_px_; }
  const Eigen::Matrix3d& K() const { return K_; }
  const Eigen::Matrix3d& Kinv() const { return K_inv_; }
  DistortionModel distortionModel() const { return model_; }
  // The model's coefficients, as many as distortionCoefficientCount(distortionModel()).
  const std::vector<double>& coefficients() const { return coefficients_; }
  // plumb_bob's k1, k2, p1, p2, k3 (zero for the other models: check distortionModel()).
  const Eigen::Matrix<double, 5, 1>& distortion() const { return plumb_bob_; }
  bool hasDistortion() const { return has_distortion_; }

  // Undistorted pixel -> raw (distorted) pixel.
  Eigen::Vector2d distort(const Eigen::Vector2d& undistorted_px) const;
  // Raw (distorted) pixel -> undistorted pixel (OpenCV's iterative undistortion run to 1e-12 in
  // normalised coordinates, ~1e-9 px).
  Eigen::Vector2d undistort(const Eigen::Vector2d& distorted_px) const;
  // The same for many points at once (one OpenCV call; what per-frame code uses), in place.
  void distortPoints(std::vector<Eigen::Vector2d>& px) const;
  void undistortPoints(std::vector<Eigen::Vector2d>& px) const;

  bool operator==(const CameraModel& other) const;
  bool operator!=(const CameraModel& other) const { return !(*this == other); }

 private:
  int width_px_ = 0;
  int height_px_ = 0;
  Eigen::Matrix3d K_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d K_inv_ = Eigen::Matrix3d::Identity();
  DistortionModel model_ = DistortionModel::kPlumbBob;
  std::vector<double> coefficients_ = std::vector<double>(5, 0.0);
  Eigen::Matrix<double, 5, 1> plumb_bob_ = Eigen::Matrix<double, 5, 1>::Zero();
  bool has_distortion_ = false;
};

}  // namespace deep_ois
