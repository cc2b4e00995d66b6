// The backward map from row-patch homographies (patch_homography_map.h) against the exact per-pixel
// mapping: every patch's distort(H_i^-1 undistort(q)) computed with the camera model for every
// pixel, the patch picked by the documented rule. Within 0.01 px everywhere, except where the exact
// rows put a pixel within 0.01 px of a patch boundary (there a hair's difference may pick the
// neighbouring patch, both being right to that hair); and the fixed-point form warps as the float
// map does.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/patch_homography_map.h"

namespace deep_ois {
namespace {

constexpr double kTolerancePx = 0.01;

CameraModel camera70Degrees(cv::Size size, const std::vector<double>& plumb_bob = {}) {
  const double f = 0.5 * size.width / std::tan(35.0 * M_PI / 180.0);
  Eigen::Matrix3d K;
  K << f, 0, 0.5 * (size.width - 1), 0, f, 0.5 * (size.height - 1), 0, 0, 1;
  return CameraModel(size.width, size.height, K, plumb_bob);
}

// A rotation about an oblique axis that speeds up during readout: patch i turns by
// angle * (1 + rolling_step * i), so neighbouring patches' images meet with gaps and overlaps.
std::vector<Eigen::Matrix3d> rollingRotation(const CameraModel& camera, double angle_rad, int patches,
                                             double rolling_step) {
  std::vector<Eigen::Matrix3d> homographies;
  for (int i = 0; i < patches; ++i) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(angle_rad * (1.0 + rolling_step * i), Eigen::Vector3d(0.3, 1.0, 0.4).normalized())
            .toRotationMatrix();
    homographies.push_back(camera.K() * R * camera.Kinv());
  }
  return homographies;
}

struct Comparison {
  double largest_px = 0.0;           // over every pixel but those counted below
  std::size_t near_boundary = 0;     // pixels that picked another patch, the exact row at a boundary
  std::size_t wrong_patch = 0;       // pixels that picked another patch anywhere else
};

// Every pixel of `fast` against the exact mapping, every patch evaluated per pixel.
Comparison compareWithExact(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& homographies,
                            const cv::Mat& fast) {
  const PatchRows rows(camera.height(), static_cast<int>(homographies.size()));
  std::vector<Eigen::Matrix3d> inverse;
  for (const Eigen::Matrix3d& H : homographies) inverse.push_back(H.inverse());
  std::vector<Eigen::Vector2d> undistorted;
  for (int y = 0; y < camera.height(); ++y) {
    for (int x = 0; x < camera.width(); ++x) undistorted.emplace_back(x, y);
  }
  camera.undistortPoints(undistorted);
  std::vector<std::vector<Eigen::Vector2d>> per_patch;
  for (const Eigen::Matrix3d& G : inverse) {
    std::vector<Eigen::Vector2d> positions;
    for (const Eigen::Vector2d& u : undistorted) positions.push_back((G * u.homogeneous()).hnormalized());
    camera.distortPoints(positions);
    per_patch.push_back(positions);
  }
  std::vector<int> patches(homographies.size());
  for (std::size_t i = 0; i < patches.size(); ++i) patches[i] = static_cast<int>(i);
  Comparison result;
  std::vector<double> y_px(patches.size());
  for (int y = 0; y < camera.height(); ++y) {
    for (int x = 0; x < camera.width(); ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * camera.width() + x;
      for (std::size_t i = 0; i < patches.size(); ++i) y_px[i] = per_patch[i][k].y();
      const Eigen::Vector2d& exact = per_patch[rows.select(patches.data(), y_px, patches.size())][k];
      const cv::Vec2f& got = fast.at<cv::Vec2f>(y, x);
      const double difference = std::max(std::abs(got[0] - exact.x()), std::abs(got[1] - exact.y()));
      if (difference <= kTolerancePx) {
        result.largest_px = std::max(result.largest_px, difference);
        continue;
      }
      bool at_boundary = false;
      for (std::size_t i = 0; i < patches.size(); ++i) {
        at_boundary = at_boundary || std::abs(y_px[i] - rows.lower_px[i]) < kTolerancePx ||
                      std::abs(y_px[i] - rows.upper_px[i]) < kTolerancePx;
      }
      bool other_patch = false;
      for (std::size_t i = 0; i < patches.size(); ++i) {
        other_patch = other_patch || (std::abs(got[0] - per_patch[i][k].x()) <= kTolerancePx &&
                                      std::abs(got[1] - per_patch[i][k].y()) <= kTolerancePx);
      }
      if (other_patch && at_boundary) {
        ++result.near_boundary;
      } else if (other_patch) {
        ++result.wrong_patch;
      } else {
        result.largest_px = std::max(result.largest_px, difference);
      }
    }
  }
  return result;
}

TEST(PatchHomographyMap, MatchesTheExactMappingWithoutDistortion) {
  const CameraModel camera = camera70Degrees(cv::Size(640, 480));
  const std::vector<Eigen::Matrix3d> homographies = rollingRotation(camera, 0.05, 6, 0.02);
  const PatchHomographyMapBuilder builder(camera, 6);
  EXPECT_EQ(builder.latticeStepPx(), 16);
  const Comparison c = compareWithExact(camera, homographies, builder.buildFloat(homographies));
  std::printf("no distortion: largest %.5f px, %zu pixels on the neighbouring patch at a boundary, %zu elsewhere\n",
              c.largest_px, c.near_boundary, c.wrong_patch);
  EXPECT_LE(c.largest_px, kTolerancePx);
  EXPECT_EQ(c.wrong_patch, 0u);
  EXPECT_LE(c.near_boundary, 10u);
}

TEST(PatchHomographyMap, MatchesTheExactMappingWithStrongDistortion) {
  // Barrel distortion of a wide lens (the corners move by ~40 px) on a small image, where the
  // distortion bends fastest per pixel; the rolling rotation makes seams of a few pixels. (A
  // bilinear lattice interpolation erred by 0.39 px here, hence the cubic.)
  const CameraModel camera = camera70Degrees(cv::Size(320, 240), {-0.25, 0.08, 0.001, -0.001, 0.0});
  const std::vector<Eigen::Matrix3d> homographies = rollingRotation(camera, 0.05, 6, 0.03);
  const PatchHomographyMapBuilder builder(camera, 6);
  EXPECT_EQ(builder.latticeStepPx(), 8);
  const Comparison c = compareWithExact(camera, homographies, builder.buildFloat(homographies));
  std::printf("distortion: largest %.5f px, %zu pixels on the neighbouring patch at a boundary, %zu elsewhere\n",
              c.largest_px, c.near_boundary, c.wrong_patch);
  EXPECT_LE(c.largest_px, kTolerancePx);
  EXPECT_EQ(c.wrong_patch, 0u);
  EXPECT_LE(c.near_boundary, 10u);
  // The documented reference function agrees with the comparison's own per-pixel evaluation.
  const PatchRows rows(camera.height(), 6);
  const cv::Mat fast = builder.buildFloat(homographies);
  for (const cv::Point q : {cv::Point(0, 0), cv::Point(160, 120), cv::Point(319, 239), cv::Point(17, 80)}) {
    const Eigen::Vector2d exact = exactPatchBackwardPosition(camera, homographies, rows, Eigen::Vector2d(q.x, q.y));
    EXPECT_NEAR(fast.at<cv::Vec2f>(q)[0], exact.x(), kTolerancePx);
    EXPECT_NEAR(fast.at<cv::Vec2f>(q)[1], exact.y(), kTolerancePx);
  }
}

TEST(PatchHomographyMap, FixedPointWarpEqualsTheFloatMapWarp) {
  const CameraModel camera = camera70Degrees(cv::Size(320, 240), {-0.1, 0.01});
  const std::vector<Eigen::Matrix3d> homographies = rollingRotation(camera, 0.03, 6, 0.02);
  const PatchHomographyMapBuilder builder(camera, 6);
  FixedPointMap map;
  builder.build(homographies, map);
  ASSERT_EQ(map.size(), cv::Size(320, 240));
  cv::Mat image(240, 320, CV_8UC3), warped;
  cv::randu(image, 0, 255);
  warpWithFixedPointMap(image, map, warped);
  EXPECT_EQ(cv::norm(warped, warpWithInverseMap(image, builder.buildFloat(homographies)), cv::NORM_INF), 0.0);
}

TEST(PatchHomographyMap, IdentityHomographiesGiveTheIdentityMap) {
  const CameraModel camera = camera70Degrees(cv::Size(200, 150), {-0.2, 0.05});
  const PatchHomographyMapBuilder builder(camera, 3, 8);
  const cv::Mat map = builder.buildFloat(std::vector<Eigen::Matrix3d>(3, Eigen::Matrix3d::Identity()));
  double largest = 0.0;
  for (int y = 0; y < map.rows; ++y) {
    for (int x = 0; x < map.cols; ++x) {
      largest = std::max({largest, std::abs(static_cast<double>(map.at<cv::Vec2f>(y, x)[0]) - x),
                          std::abs(static_cast<double>(map.at<cv::Vec2f>(y, x)[1]) - y)});
    }
  }
  EXPECT_LE(largest, 1e-3);
}

TEST(PatchHomographyMap, RejectsBadInput) {
  const CameraModel camera = camera70Degrees(cv::Size(64, 48));
  EXPECT_THROW(PatchHomographyMapBuilder(camera, 0), std::invalid_argument);
  EXPECT_THROW(PatchHomographyMapBuilder(camera, 6, 1), std::invalid_argument);
  EXPECT_THROW(PatchHomographyMapBuilder(camera, 6, -3), std::invalid_argument);
  const PatchHomographyMapBuilder builder(camera, 6);
  FixedPointMap map;
  EXPECT_THROW(builder.build(std::vector<Eigen::Matrix3d>(5, Eigen::Matrix3d::Identity()), map),
               std::invalid_argument);
  std::vector<Eigen::Matrix3d> singular(6, Eigen::Matrix3d::Identity());
  singular[2].setZero();
  EXPECT_THROW(builder.build(singular, map), std::invalid_argument);
  singular[2] = Eigen::Matrix3d::Identity();
  singular[4](0, 0) = std::nan("");
  EXPECT_THROW(builder.build(singular, map), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
