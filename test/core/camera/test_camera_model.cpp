// The three CameraInfo distortion models against OpenCV: distort() must equal cv::projectPoints /
// cv::fisheye::projectPoints of the same ray, and undistort() must invert distort() (round trip)
// over the whole image.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"

namespace deep_ois {
namespace {

constexpr int kWidthPx = 640, kHeightPx = 480;

Eigen::Matrix3d testK() {
  Eigen::Matrix3d K;
  K << 420.0, 0.0, 322.5, 0.0, 418.0, 241.0, 0.0, 0.0, 1.0;
  return K;
}

struct ModelCase {
  DistortionModel model;
  std::vector<double> coefficients;
};

// Realistic lenses: a phone (plumb_bob), a wide-angle (rational_polynomial), a fisheye (equidistant).
std::vector<ModelCase> cases() {
  return {{DistortionModel::kPlumbBob, {-0.12, 0.03, 0.0005, -0.0003, 0.002}},
          {DistortionModel::kRationalPolynomial, {0.35, -0.08, 0.0004, -0.0002, 0.01, 0.62, -0.05, 0.02}},
          {DistortionModel::kEquidistant, {-0.02, 0.004, -0.001, 0.0002}}};
}

// Grid over the image, corners included (raw pixels).
std::vector<Eigen::Vector2d> imageGrid() {
  std::vector<Eigen::Vector2d> px;
  for (int y = 0; y <= 12; ++y)
    for (int x = 0; x <= 16; ++x) px.emplace_back(x * (kWidthPx - 1) / 16.0, y * (kHeightPx - 1) / 12.0);
  return px;
}

TEST(CameraModel, NamesAndCoefficientCounts) {
  EXPECT_STREQ(distortionModelName(DistortionModel::kPlumbBob), "plumb_bob");
  EXPECT_STREQ(distortionModelName(DistortionModel::kRationalPolynomial), "rational_polynomial");
  EXPECT_STREQ(distortionModelName(DistortionModel::kEquidistant), "equidistant");
  EXPECT_EQ(distortionCoefficientCount(DistortionModel::kRationalPolynomial), 8u);
  EXPECT_EQ(distortionCoefficientCount(DistortionModel::kEquidistant), 4u);
  // Too many coefficients are named, not truncated.
  const CameraModel bad(kWidthPx, kHeightPx, testK(), DistortionModel::kEquidistant, {0.1, 0.0, 0.0, 0.0, 0.3});
  EXPECT_NE(bad.validate().find("equidistant distortion has 5 coefficients, expected at most 4"), std::string::npos)
      << bad.validate();
}

TEST(CameraModel, DistortMatchesOpenCvProjection) {
  const Eigen::Matrix3d K = testK();
  const cv::Matx33d cv_K(K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), 0.0, 0.0, 1.0);
  for (const ModelCase& c : cases()) {
    SCOPED_TRACE(distortionModelName(c.model));
    const CameraModel camera(kWidthPx, kHeightPx, K, c.model, c.coefficients);
    ASSERT_EQ(camera.validate(), "");
    ASSERT_TRUE(camera.hasDistortion());
    double worst_px = 0.0;
    for (const Eigen::Vector2d& raw : imageGrid()) {
      // A ray through an undistorted pixel, projected by OpenCV's own projection of the model.
      const Eigen::Vector2d undistorted = camera.undistort(raw);
      const Eigen::Vector3d ray = K.inverse() * undistorted.homogeneous();
      std::vector<cv::Point3d> object{cv::Point3d(ray.x(), ray.y(), ray.z())};
      std::vector<cv::Point2d> image;
      if (c.model == DistortionModel::kEquidistant) {
        cv::fisheye::projectPoints(object, image, cv::Vec3d::all(0.0), cv::Vec3d::all(0.0), cv_K, c.coefficients);
      } else {
        cv::projectPoints(object, cv::Vec3d::all(0.0), cv::Vec3d::all(0.0), cv_K, c.coefficients, image);
      }
      const Eigen::Vector2d distorted = camera.distort(undistorted);
      worst_px = std::max(worst_px, (distorted - Eigen::Vector2d(image[0].x, image[0].y)).norm());
    }
    std::printf("[ INFO     ] %s: distort vs OpenCV projectPoints: worst %.2e px\n", distortionModelName(c.model),
                worst_px);
    EXPECT_LT(worst_px, 1e-9);
  }
}

TEST(CameraModel, UndistortInvertsDistortOverTheImage) {
  for (const ModelCase& c : cases()) {
    SCOPED_TRACE(distortionModelName(c.model));
    const CameraModel camera(kWidthPx, kHeightPx, testK(), c.model, c.coefficients);
    std::vector<Eigen::Vector2d> raw = imageGrid();
    std::vector<Eigen::Vector2d> round_trip = raw;
    camera.undistortPoints(round_trip);
    double largest_shift_px = 0.0;
    for (std::size_t i = 0; i < raw.size(); ++i) {
      largest_shift_px = std::max(largest_shift_px, (round_trip[i] - raw[i]).norm());
    }
    camera.distortPoints(round_trip);
    double worst_px = 0.0;
    for (std::size_t i = 0; i < raw.size(); ++i) worst_px = std::max(worst_px, (round_trip[i] - raw[i]).norm());
    std::printf("[ INFO     ] %s: distortion moves pixels by up to %.1f px; round trip worst %.2e px\n",
                distortionModelName(c.model), largest_shift_px, worst_px);
    EXPECT_GT(largest_shift_px, 5.0) << "the test lens must distort noticeably";
    EXPECT_LT(worst_px, 1e-6);
    // The one-point functions agree with the batch ones.
    EXPECT_LT((camera.distort(camera.undistort(raw.front())) - raw.front()).norm(), 1e-6);
  }
}

TEST(CameraModel, SkewIsAppliedOutsideTheDistortion) {
  // Distortion acts on normalised coordinates; K (with its skew) maps them to pixels.
  Eigen::Matrix3d K = testK();
  K(0, 1) = 0.8;
  const CameraModel camera(kWidthPx, kHeightPx, K, DistortionModel::kPlumbBob, {-0.1, 0.02, 0.0, 0.0, 0.0});
  const Eigen::Vector2d xy(0.3, -0.2);
  const double r2 = xy.squaredNorm(), radial = 1.0 - 0.1 * r2 + 0.02 * r2 * r2;
  const Eigen::Vector2d expected = (K * (xy * radial).homogeneous()).hnormalized();
  EXPECT_LT((camera.distort((K * xy.homogeneous()).hnormalized()) - expected).norm(), 1e-9);
}

}  // namespace
}  // namespace deep_ois
