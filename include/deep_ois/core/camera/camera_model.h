// Pinhole camera with optional plumb_bob (Brown-Conrady) distortion, as in sensor_msgs/CameraInfo.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace deep_ois {

// Pixel convention everywhere in deep_ois: OpenCV's, x right, y down, (0, 0) = centre of the
// top-left pixel. `K` maps normalised camera coordinates (x/z, y/z) of the optical frame to
// undistorted pixels; distortion, when present, moves undistorted pixels to the raw image.
class CameraModel {
 public:
  CameraModel() = default;
  // `plumb_bob` holds k1, k2, p1, p2, k3 (CameraInfo's D); fewer entries are zero-padded, an empty
  // vector means no distortion.
  CameraModel(int width_px, int height_px, const Eigen::Matrix3d& K,
              const std::vector<double>& plumb_bob = {});

  // Empty when the model is usable; otherwise a sentence naming what is wrong.
  std::string validate() const;

  int width() const { return width_px_; }
  int height() const { return height_px_; }
  const Eigen::Matrix3d& K() const { return K_; }
  const Eigen::Matrix3d& Kinv() const { return K_inv_; }
  // k1, k2, p1, p2, k3.
  const Eigen::Matrix<double, 5, 1>& distortion() const { return distortion_; }
  bool hasDistortion() const { return has_distortion_; }

  // Undistorted pixel -> raw (distorted) pixel.
  Eigen::Vector2d distort(const Eigen::Vector2d& undistorted_px) const;
  // Raw (distorted) pixel -> undistorted pixel, by Gauss-Newton on distort(); converges to
  // 1e-9 px for the distortion a real lens has inside its image.
  Eigen::Vector2d undistort(const Eigen::Vector2d& distorted_px) const;

  bool operator==(const CameraModel& other) const;
  bool operator!=(const CameraModel& other) const { return !(*this == other); }

 private:
  // Distortion in normalised coordinates, with its 2x2 Jacobian when `jacobian` is not null.
  Eigen::Vector2d distortNormalised(const Eigen::Vector2d& xy, Eigen::Matrix2d* jacobian) const;

  int width_px_ = 0;
  int height_px_ = 0;
  Eigen::Matrix3d K_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d K_inv_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 5, 1> distortion_ = Eigen::Matrix<double, 5, 1>::Zero();
  bool has_distortion_ = false;
};

}  // namespace deep_ois
