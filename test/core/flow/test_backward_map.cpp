// The backward map built on the working grid (backward_map.h) against the per-camera-pixel
// inversion it replaces (inverseFlowMap, the reference): within 0.01 px over the whole image on a
// strong rotation at 1920x1080, and the fixed-point form warps exactly as cv::remap with the float
// map does.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/flow/homography_flow.h"

namespace deep_ois {
namespace {

// A rotation of `angle_rad` about an oblique axis seen by a 70-degree camera of `camera_size`,
// rendered on the 360x270 working grid with `patches` row patches; patch i turns by
// angle * (1 + rolling_step * i) (a rotation that speeds up during readout).
cv::Mat rotationFlow(cv::Size camera_size, double angle_rad, int patches, double rolling_step) {
  const double f = 0.5 * camera_size.width / std::tan(35.0 * M_PI / 180.0);
  Eigen::Matrix3d K;
  K << f, 0, 0.5 * (camera_size.width - 1), 0, f, 0.5 * (camera_size.height - 1), 0, 0, 1;
  const CameraModel camera(camera_size.width, camera_size.height, K);
  std::vector<Eigen::Matrix3d> homographies;
  for (int i = 0; i < patches; ++i) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(angle_rad * (1.0 + rolling_step * i), Eigen::Vector3d(0.3, 1.0, 0.4).normalized())
            .toRotationMatrix();
    homographies.push_back(K * R * K.inverse());
  }
  cv::Mat flow;
  HomographyFlowRenderer(camera, cv::Size(360, 270), patches).render(homographies, flow);
  return flow;
}

double largestDifferencePx(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  double largest = 0.0;
  cv::minMaxLoc(difference.reshape(1), nullptr, &largest);
  return largest;
}

TEST(BackwardMap, MatchesThePerPixelInversionOnAStrongRotationAt1080p) {
  const cv::Size camera(1920, 1080);
  // 0.06 rad: up to about 130 camera pixels of motion at the image corners.
  const cv::Mat flow = rotationFlow(camera, 0.06, 1, 0.0);
  const cv::Mat reference = inverseFlowMap(flow, camera, 3);
  const cv::Mat fast = backwardMapFromGrid(flow, camera, 3);
  ASSERT_EQ(fast.size(), camera);
  ASSERT_EQ(fast.type(), CV_32FC2);
  EXPECT_LE(largestDifferencePx(fast, reference), 0.01);
}

TEST(BackwardMap, MatchesThePerPixelInversionOnARollingShutterRotationAt1080p) {
  const cv::Size camera(1920, 1080);
  // Six row patches, the rotation 1 % faster in each: the patches' flows differ by up to 4 px.
  const cv::Mat flow = rotationFlow(camera, 0.06, 6, 0.01);
  EXPECT_LE(largestDifferencePx(backwardMapFromGrid(flow, camera, 3), inverseFlowMap(flow, camera, 3)), 0.01);
}

TEST(BackwardMap, FixedPointWarpEqualsTheFloatMapWarp) {
  const cv::Size camera(640, 480);
  const cv::Mat flow = rotationFlow(camera, 0.04, 6, 0.0);
  FixedPointMap fixed;
  buildFixedPointBackwardMap(flow, camera, 3, fixed);
  ASSERT_EQ(fixed.size(), camera);
  cv::Mat image(camera, CV_8UC3);
  cv::randu(image, 0, 255);
  cv::Mat warped;
  warpWithFixedPointMap(image, fixed, warped);
  // cv::remap rounds a float map to the same 1/32 pixel: the two warps are the same image.
  const cv::Mat expected = warpWithInverseMap(image, backwardMapFromGrid(flow, camera, 3));
  EXPECT_EQ(cv::norm(warped, expected, cv::NORM_INF), 0.0);

  // A caller's buffer of the right size and type receives the result in place.
  std::vector<unsigned char> buffer(camera.area() * 3);
  cv::Mat view(camera, CV_8UC3, buffer.data());
  warpWithFixedPointMap(image, fixed, view);
  EXPECT_EQ(view.data, buffer.data());
  EXPECT_EQ(cv::norm(view, expected, cv::NORM_INF), 0.0);
}

// The live nodelet writes the ghost into its message's buffer, or over the warped frame itself.
TEST(GhostOverlay, IntoABufferAndInPlaceEqualTheAllocatingForm) {
  cv::Mat a(48, 64, CV_8UC3), b(48, 64, CV_8UC3);
  cv::randu(a, 0, 255);
  cv::randu(b, 0, 255);
  const cv::Mat expected = ghostOverlay(a, b);
  for (int y = 0; y < a.rows; ++y) {
    for (int x = 0; x < a.cols; ++x) {
      const cv::Vec3b& g = expected.at<cv::Vec3b>(y, x);
      ASSERT_EQ(g, cv::Vec3b(b.at<cv::Vec3b>(y, x)[0], a.at<cv::Vec3b>(y, x)[1], a.at<cv::Vec3b>(y, x)[2]));
    }
  }
  std::vector<unsigned char> buffer(a.total() * 3);
  cv::Mat into(a.size(), CV_8UC3, buffer.data());
  ghostOverlay(a, b, into);
  EXPECT_EQ(into.data, buffer.data());
  EXPECT_EQ(cv::norm(into, expected, cv::NORM_INF), 0.0);
  cv::Mat in_place = a.clone();
  ghostOverlay(in_place, b, in_place);
  EXPECT_EQ(cv::norm(in_place, expected, cv::NORM_INF), 0.0);
  cv::Mat out;
  EXPECT_THROW(ghostOverlay(a, cv::Mat(10, 10, CV_8UC3), out), std::invalid_argument);
}

TEST(BackwardMap, RejectsBadInput) {
  FixedPointMap map;
  EXPECT_THROW(inverseDisplacementOnGrid(cv::Mat(), cv::Size(10, 10)), std::invalid_argument);
  EXPECT_THROW(inverseDisplacementOnGrid(cv::Mat(4, 4, CV_32FC1), cv::Size(10, 10)), std::invalid_argument);
  EXPECT_THROW(buildFixedPointBackwardMap(cv::Mat(4, 4, CV_32FC2), cv::Size(0, 10), 3, map), std::invalid_argument);
  EXPECT_THROW(backwardMapFromGrid(cv::Mat(4, 4, CV_32FC2), cv::Size(10, 10), -1), std::invalid_argument);
  buildFixedPointBackwardMap(cv::Mat(4, 4, CV_32FC2, cv::Scalar(0, 0)), cv::Size(10, 10), 3, map);
  cv::Mat out;
  EXPECT_THROW(warpWithFixedPointMap(cv::Mat(8, 10, CV_8UC1), map, out), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
