#include <gtest/gtest.h>

#include <cmath>

#include "deep_ois/core/flow/flow_color.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

using test::applyHomography;

std::vector<Eigen::Matrix3d> twoPatchHomographies(const Eigen::Matrix3d& K) {
  return {rotationHomography(K, expSO3(Eigen::Vector3d(0.01, -0.02, 0.005))),
          rotationHomography(K, expSO3(Eigen::Vector3d(-0.015, 0.01, 0.02)))};
}

TEST(HomographyFlow, FlowEqualsHomographyAppliedOnTheCameraGrid) {
  Eigen::Matrix3d K;
  K << 500, 0, 399.5, 0, 500, 299.5, 0, 0, 1;
  const CameraModel camera(800, 600, K);
  const HomographyFlowRenderer renderer(camera, cv::Size(400, 300), 2);
  const auto H = twoPatchHomographies(K);
  cv::Mat flow;
  renderer.render(H, flow);
  ASSERT_EQ(flow.type(), CV_32FC2);
  ASSERT_EQ(flow.size(), cv::Size(400, 300));
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(2.0, 2.0), renderer.scale(), 0.0);
  for (int gy : {0, 77, 149, 150, 299}) {
    for (int gx : {0, 123, 399}) {
      const Eigen::Vector2d p = renderer.gridToCamera(gx, gy);
      const int patch = p.y() < 300 ? 0 : 1;
      const Eigen::Vector2d expected = (applyHomography(H[patch], p) - p) / 2.0;
      const cv::Vec2f got = flow.at<cv::Vec2f>(gy, gx);
      EXPECT_NEAR(expected.x(), got[0], 1e-4) << gx << "," << gy;
      EXPECT_NEAR(expected.y(), got[1], 1e-4) << gx << "," << gy;
    }
  }
  // Grid pixel centres line up with camera pixel centres.
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(0.5, 0.5), renderer.gridToCamera(0, 0), 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(798.5, 598.5), renderer.gridToCamera(399, 299), 1e-12);
}

TEST(HomographyFlow, IdentityGivesZeroFlow) {
  const CameraModel camera(360, 270, test::phoneLikeK());
  const HomographyFlowRenderer renderer(camera, cv::Size(360, 270), 6);
  cv::Mat flow;
  renderer.render(std::vector<Eigen::Matrix3d>(6, Eigen::Matrix3d::Identity()), flow);
  EXPECT_EQ(cv::norm(flow, cv::NORM_INF), 0.0);
  EXPECT_THROW(renderer.render(std::vector<Eigen::Matrix3d>(5, Eigen::Matrix3d::Identity()), flow),
               std::invalid_argument);
}

TEST(CameraModel, DistortionRoundTrips) {
  Eigen::Matrix3d K;
  K << 500, 0, 399.5, 0, 500, 299.5, 0, 0, 1;
  // Barrel distortion of a wide phone lens; monotonic out to the image corners (r = 1).
  const CameraModel camera(800, 600, K, {-0.28, 0.09, 0.001, -0.0007, -0.01});
  ASSERT_TRUE(camera.hasDistortion());
  for (double x : {0.0, 100.0, 400.0, 799.0}) {
    for (double y : {0.0, 300.0, 599.0}) {
      const Eigen::Vector2d raw(x, y);
      EXPECT_MATRIX_NEAR(raw, camera.distort(camera.undistort(raw)), 1e-9);
    }
  }
  EXPECT_NE(CameraModel(0, 10, test::phoneLikeK()).validate(), "");
}

TEST(HomographyFlow, DistortedFlowIsDistortOfHomographyOfUndistort) {
  Eigen::Matrix3d K;
  K << 420, 0, 180, 0, 420, 135, 0, 0, 1;
  const CameraModel camera(360, 270, K, {-0.2, 0.05, 0.0005, 0.0002, 0.0});
  const HomographyFlowRenderer renderer(camera, cv::Size(180, 135), 2);
  const auto H = twoPatchHomographies(K);
  cv::Mat flow;
  renderer.render(H, flow);
  for (int gy : {0, 60, 134}) {
    for (int gx : {0, 90, 179}) {
      const Eigen::Vector2d p = renderer.gridToCamera(gx, gy);
      const Eigen::Vector2d expected =
          (camera.distort(applyHomography(H[p.y() < 135 ? 0 : 1], camera.undistort(p))) - p) / 2.0;
      const cv::Vec2f got = flow.at<cv::Vec2f>(gy, gx);
      EXPECT_NEAR(expected.x(), got[0], 1e-4);
      EXPECT_NEAR(expected.y(), got[1], 1e-4);
    }
  }
}

TEST(FlowColor, HueEncodesDirectionAndValueMagnitude) {
  cv::Mat flow(1, 4, CV_32FC2);
  flow.at<cv::Vec2f>(0, 0) = cv::Vec2f(2, 0);   // right: red
  flow.at<cv::Vec2f>(0, 1) = cv::Vec2f(-2, 0);  // left: cyan
  flow.at<cv::Vec2f>(0, 2) = cv::Vec2f(1, 0);   // half magnitude
  flow.at<cv::Vec2f>(0, 3) = cv::Vec2f(0, 0);   // still: black
  const cv::Mat rgb = colorizeFlow(flow, 2.0);
  ASSERT_EQ(rgb.type(), CV_8UC3);
  EXPECT_EQ(rgb.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 0, 0));
  EXPECT_EQ(rgb.at<cv::Vec3b>(0, 1), cv::Vec3b(0, 255, 255));
  EXPECT_NEAR(rgb.at<cv::Vec3b>(0, 2)[0], 128, 1);
  EXPECT_EQ(rgb.at<cv::Vec3b>(0, 3), cv::Vec3b(0, 0, 0));
  // Automatic scale: the largest vector gets full value.
  EXPECT_EQ(colorizeFlow(flow).at<cv::Vec3b>(0, 0), cv::Vec3b(255, 0, 0));
}

}  // namespace
}  // namespace deep_ois
