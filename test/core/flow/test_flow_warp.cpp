// Flow resampling between grids and the inversion of a forward flow for warping frame a onto b.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "deep_ois/core/flow/flow_resample.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/homography_flow.h"

namespace deep_ois {
namespace {

TEST(FlowResample, ScalesValuesWithTheGrid) {
  const cv::Mat flow(27, 36, CV_32FC2, cv::Scalar(2.0, -1.0));
  const cv::Mat camera = resampleFlow(flow, cv::Size(360, 270));
  ASSERT_EQ(camera.size(), cv::Size(360, 270));
  const cv::Vec2f value = camera.at<cv::Vec2f>(100, 200);
  EXPECT_NEAR(value[0], 20.0, 1e-5);
  EXPECT_NEAR(value[1], -10.0, 1e-5);
  const cv::Mat back = resampleFlow(camera, cv::Size(36, 27));
  EXPECT_LT(cv::norm(back, flow, cv::NORM_INF), 1e-4);
  EXPECT_THROW(resampleFlow(cv::Mat(), cv::Size(3, 3)), std::invalid_argument);
}

TEST(FlowWarp, InvertsAHomographyFlowAndWarpsLikeWarpPerspective) {
  Eigen::Matrix3d K;
  K << 250, 0, 179.5, 0, 250, 134.5, 0, 0, 1;
  const CameraModel camera(360, 270, K);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.03, Eigen::Vector3d(0.3, 1.0, 0.2).normalized()).toRotationMatrix();
  Eigen::Matrix3d H = K * R * K.inverse();
  H /= H(2, 2);
  HomographyFlowRenderer renderer(camera, cv::Size(360, 270), 1);
  cv::Mat flow;
  renderer.render({H}, flow);  // about 7.5 px of motion

  // Every pixel q of frame b maps back to p with H p = q.
  const cv::Mat map = inverseFlowMap(flow, cv::Size(360, 270), 3);
  double worst = 0.0;
  for (int y = 20; y < 250; y += 23) {
    for (int x = 20; x < 340; x += 29) {
      const cv::Vec2f p = map.at<cv::Vec2f>(y, x);
      const Eigen::Vector2d q = (H * Eigen::Vector3d(p[0], p[1], 1.0)).hnormalized();
      worst = std::max(worst, (q - Eigen::Vector2d(x, y)).norm());
    }
  }
  EXPECT_LT(worst, 0.01);

  cv::Mat image(270, 360, CV_8UC3);
  cv::randu(image, 0, 255);
  cv::GaussianBlur(image, image, cv::Size(7, 7), 2.0);
  const cv::Mat warped = warpOntoLaterFrame(image, flow);
  cv::Mat expected;
  cv::Mat H_cv;
  cv::Mat(cv::Matx33d(H(0, 0), H(0, 1), H(0, 2), H(1, 0), H(1, 1), H(1, 2), H(2, 0), H(2, 1), H(2, 2))).copyTo(H_cv);
  cv::warpPerspective(image, expected, H_cv, image.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  const cv::Rect inside(30, 30, 300, 210);
  EXPECT_LT(cv::norm(warped(inside), expected(inside), cv::NORM_L1) / (inside.area() * 3.0), 1.0);
}

}  // namespace
}  // namespace deep_ois
