// The simulated scene: ray-plane intersection and texture sampling on hand-made planes, and the
// category layouts built from the installed photographs (coverage of the view over the whole
// motion, parallax layers, the moving object, texture pre-filtering, determinism, errors).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <tuple>

#include "deep_ois/core/sim/scene.h"
#include "deep_ois/core/sim/sim_camera.h"
#include "test_helpers.h"
#include "sim_test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kStartS = -0.25;
constexpr double kEndS = 2.0;

// A plane facing a camera that looks along world +x: u to the image right (world -y), v down
// (world -z); its top-left corner at (x, y_left, z_top).
TexturedPlane frontoPlane(double x, double y_left, double z_top, double width_m, double height_m) {
  TexturedPlane plane;
  plane.origin_world_m = Eigen::Vector3d(x, y_left, z_top);
  plane.axis_u = -Eigen::Vector3d::UnitY();
  plane.axis_v = -Eigen::Vector3d::UnitZ();
  plane.width_m = width_m;
  plane.height_m = height_m;
  plane.texture = cv::Mat(2, 2, CV_32FC3, cv::Scalar::all(0.5));
  return plane;
}

bool photosInstalled() { return !defaultTexturePaths().empty(); }

Eigen::Vector3d middle(const TexturedPlane& plane) {
  return plane.origin_world_m + 0.5 * plane.width_m * plane.axis_u +
         0.5 * plane.height_m * plane.axis_v;
}

// Distance from `point` to the (static) plane's infinite extension.
double distanceAlongNormal(const TexturedPlane& plane, const Eigen::Vector3d& point) {
  return std::abs(plane.axis_u.cross(plane.axis_v).dot(plane.origin_world_m - point));
}

#define SKIP_WITHOUT_PHOTOS()                               \
  if (!photosInstalled())                                   \
  GTEST_SKIP() << "mate-backgrounds is not installed (run " \
                  "scripts/install_deps.sh)"

// The hand-held motion, OIS and 360x270 camera the layouts are built for.
struct Rig : test::Rig {
  explicit Rig(std::uint32_t seed, const SensorConfig& sensor_config = SensorConfig())
      : test::Rig(kStartS, kEndS, sensor_config, seed) {}
};

// Built scenes are reused across tests (reading the photographs is the slow part).
struct Built {
  std::unique_ptr<Rig> rig;
  Scene scene;
};

const Built& built(Category category, std::uint32_t seed) {
  static std::map<std::pair<int, std::uint32_t>, Built> cache;
  const auto key = std::make_pair(static_cast<int>(category), seed);
  auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  Built entry;
  entry.rig = std::make_unique<Rig>(seed);
  entry.scene = buildScene(SceneConfig(), category, seed, entry.rig->motion, entry.rig->focalPx(),
                           entry.rig->sensor.supersampling);
  return cache.emplace(key, std::move(entry)).first->second;
}

// What each pixel of a (step_px-spaced) grid sees at the time its row is exposed in the frame
// stamped `stamp_s`: the index of the plane it hits, -1 for a miss.
std::vector<int> visiblePlanes(const Rig& rig, const Scene& scene, double stamp_s, int step_px) {
  std::vector<int> seen;
  const int w = rig.sensor.width_px, h = rig.sensor.height_px;
  for (int y = 0; y < h; y += step_px) {
    for (int x = 0; x < w; x += step_px) {
      // Include the outermost pixel edges: the border must be covered too.
      const Eigen::Vector2d pixel(x == 0 ? -0.5 : x, y == 0 ? -0.5 : y);
      const double t = rig.camera.rowTime(stamp_s, pixel.y());
      SceneHit hit;
      const bool any = scene.intersect(rig.motion.pose(t).centre_world_m,
                                       rig.camera.rayDirectionWorld(pixel, t), t, &hit);
      seen.push_back(any ? hit.plane_index : -1);
    }
  }
  return seen;
}

// Frame stamps spread over the motion (the last one still reads out before the end).
std::vector<double> stampsOverMotion(int count) {
  std::vector<double> stamps;
  for (int k = 0; k < count; ++k)
    stamps.push_back(kStartS + (kEndS - kStartS - 0.05) * k / (count - 1));
  return stamps;
}

TEST(SceneIntersect, ReturnsTheNearestPlane) {
  const Scene scene(
      {frontoPlane(10.0, 5.0, 5.0, 10.0, 10.0), frontoPlane(4.0, 1.0, 1.0, 2.0, 2.0)});
  SceneHit hit;
  ASSERT_TRUE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 0.0, &hit));
  EXPECT_EQ(hit.plane_index, 1);
  EXPECT_NEAR(hit.distance_m, 4.0, 1e-12);
  EXPECT_MATRIX_NEAR(Eigen::Vector3d(4.0, 0.0, 0.0), hit.point_world_m, 1e-12);
  EXPECT_TRUE(hit.is_static);
  // Past the small plane's left edge (y = 1 at x = 4) only the far one is in the way.
  const Eigen::Vector3d direction = Eigen::Vector3d(1.0, 0.3, 0.0).normalized();
  ASSERT_TRUE(scene.intersect(Eigen::Vector3d::Zero(), direction, 0.0, &hit));
  EXPECT_EQ(hit.plane_index, 0);
  EXPECT_NEAR(hit.distance_m, 10.0 / direction.x(), 1e-12);
  // The order of the planes in the list does not matter.
  const Scene swapped(
      {frontoPlane(4.0, 1.0, 1.0, 2.0, 2.0), frontoPlane(10.0, 5.0, 5.0, 10.0, 10.0)});
  ASSERT_TRUE(swapped.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 0.0, &hit));
  EXPECT_EQ(hit.plane_index, 0);
  EXPECT_NEAR(hit.distance_m, 4.0, 1e-12);
}

TEST(SceneIntersect, MissesBehindOutsideAndParallel) {
  const Scene scene({frontoPlane(10.0, 5.0, 5.0, 10.0, 10.0)});
  SceneHit hit;
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), -Eigen::Vector3d::UnitX(), 0.0, &hit));
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0.6, 0.0).normalized(),
                               0.0, &hit));
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY(), 0.0, &hit));
  // A ray in the plane itself is parallel to it: no hit, although it touches every point.
  EXPECT_FALSE(
      scene.intersect(Eigen::Vector3d(10.0, 0.0, 0.0), Eigen::Vector3d::UnitY(), 0.0, &hit));
  EXPECT_FALSE(Scene().intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 0.0, &hit));
  // Just inside the edge is a hit (the rectangle is closed).
  EXPECT_TRUE(scene.intersect(Eigen::Vector3d::Zero(),
                              Eigen::Vector3d(10.0, 4.999, 0.0).normalized(), 0.0, &hit));
}

TEST(SceneIntersect, MovingPlaneIsDisplacedByVelocityTimesTime) {
  TexturedPlane moving = frontoPlane(5.0, -1.0, 1.0, 2.0, 2.0);  // spans y in [-3, -1]
  moving.velocity_world_m_s = Eigen::Vector3d(0.0, 0.5, 0.0);
  const Scene scene({moving});
  SceneHit hit;
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 0.0, &hit));
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 1.9, &hit));
  ASSERT_TRUE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 3.0, &hit));
  EXPECT_FALSE(hit.is_static);
  EXPECT_NEAR(hit.distance_m, 5.0, 1e-12);
  // At t = 3 s the plane spans y in [-1.5, 0.5]: the ray meets it 0.5 m from its left edge.
  const TexturedPlane& plane = scene.planes()[0];
  const Eigen::Vector3d local =
      hit.point_world_m - (plane.origin_world_m + plane.velocity_world_m_s * 3.0);
  EXPECT_NEAR(local.dot(plane.axis_u), 0.5, 1e-12);
  EXPECT_NEAR(local.dot(plane.axis_v), 1.0, 1e-12);
  // Time moves it out again on the other side.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 6.1, &hit));
}

TEST(SceneIntersect, SamplesTheTextureBilinearlyAtKnownTexels) {
  // 4 x 3 texels over 3 m x 2 m: texel (i, j) sits at (u, v) = (i, j) metres.
  TexturedPlane plane = frontoPlane(2.0, 1.0, 1.0, 3.0, 2.0);
  plane.texture = cv::Mat(3, 4, CV_32FC3);
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 4; ++i) {
      plane.texture.at<cv::Vec3f>(j, i) = cv::Vec3f(0.1f * i, 0.2f * j, 0.05f * (i + j));
    }
  }
  const Scene scene({plane});
  // The ray from the origin through plane point (u, v).
  auto radianceAt = [&](double u, double v) {
    const Eigen::Vector3d target = plane.origin_world_m + u * plane.axis_u + v * plane.axis_v;
    SceneHit hit;
    EXPECT_TRUE(scene.intersect(Eigen::Vector3d::Zero(), target.normalized(), 0.0, &hit));
    return hit.radiance;
  };
  EXPECT_MATRIX_NEAR(Eigen::Vector3f(0.1f, 0.2f, 0.1f), radianceAt(1.0, 1.0), 1e-6);
  EXPECT_MATRIX_NEAR(Eigen::Vector3f(0.3f, 0.4f, 0.25f), radianceAt(3.0, 2.0), 1e-6);
  EXPECT_MATRIX_NEAR(Eigen::Vector3f(0.0f, 0.0f, 0.0f), radianceAt(0.0, 0.0), 1e-6);
  // Half-way between four texels: their mean; a quarter of the way: the bilinear weights.
  EXPECT_MATRIX_NEAR(Eigen::Vector3f(0.15f, 0.1f, 0.1f), radianceAt(1.5, 0.5), 1e-6);
  EXPECT_MATRIX_NEAR(Eigen::Vector3f(0.225f, 0.35f, 0.2f), radianceAt(2.25, 1.75), 1e-6);
}

TEST(Scene, RejectsMalformedPlanes) {
  TexturedPlane skewed = frontoPlane(2.0, 1.0, 1.0, 1.0, 1.0);
  skewed.axis_v = Eigen::Vector3d(0.0, -0.1, -1.0).normalized();
  EXPECT_THROW(Scene({skewed}), std::invalid_argument);
  TexturedPlane eight_bit = frontoPlane(2.0, 1.0, 1.0, 1.0, 1.0);
  eight_bit.texture = cv::Mat(4, 4, CV_8UC3, cv::Scalar::all(100));
  EXPECT_THROW(Scene({eight_bit}), std::invalid_argument);
  TexturedPlane flat = frontoPlane(2.0, 1.0, 1.0, 0.0, 1.0);
  EXPECT_THROW(Scene({flat}), std::invalid_argument);
}

TEST(Category, RoundTripsThroughItsName) {
  for (Category category : {Category::kRegular, Category::kLowTexture, Category::kLowLight,
                            Category::kMovingForeground}) {
    Category parsed = Category::kRegular;
    ASSERT_TRUE(parseCategory(toString(category), &parsed));
    EXPECT_EQ(parsed, category);
  }
  EXPECT_STREQ(toString(Category::kLowLight), "LL");
  Category untouched = Category::kLowTexture;
  EXPECT_FALSE(parseCategory("re", &untouched));
  EXPECT_FALSE(parseCategory("", &untouched));
  EXPECT_EQ(untouched, Category::kLowTexture);
}

TEST(SceneConfig, ValidateNamesTheBadField) {
  EXPECT_EQ(SceneConfig().validate(), "");
  auto problem = [](auto edit) {
    SceneConfig config;
    edit(config);
    return config.validate();
  };
  EXPECT_NE(problem([](SceneConfig& c) { c.near_layer_count = -1; }).find("near_layer_count"),
            std::string::npos);
  EXPECT_NE(problem([](SceneConfig& c) { c.near_depth_max_m = 1.0; }).find("near_depth"),
            std::string::npos);
  EXPECT_NE(
      problem([](SceneConfig& c) { c.background_depth_min_m = 4.0; }).find("background_depth"),
      std::string::npos);
  EXPECT_NE(
      problem([](SceneConfig& c) { c.low_texture_fraction = 1.5; }).find("low_texture_fraction"),
      std::string::npos);
  EXPECT_NE(problem([](SceneConfig& c) {
              c.moving_object_min_coverage = 0.1;
            }).find("moving_object_min_coverage"),
            std::string::npos);
  EXPECT_NE(
      problem([](SceneConfig& c) { c.moving_object_depth_m = 20.0; }).find("moving_object_depth_m"),
      std::string::npos);
  EXPECT_NE(problem([](SceneConfig& c) { c.texture_paths = {""}; }).find("texture_paths"),
            std::string::npos);
}

TEST(DefaultTexturePaths, AreTheInstalledNaturePhotographsSorted) {
  SKIP_WITHOUT_PHOTOS();
  const std::vector<std::string> paths = defaultTexturePaths();
  EXPECT_TRUE(std::is_sorted(paths.begin(), paths.end()));
  for (const std::string& path : paths) {
    EXPECT_EQ(path.rfind("/usr/share/backgrounds/mate/nature/", 0), 0u) << path;
    EXPECT_TRUE(std::ifstream(path).good()) << path;
  }
  EXPECT_GE(paths.size(), 4u);
}

TEST(BuildScene, ThrowsNamingATextureThatCannotBeRead) {
  const Rig rig(1);
  SceneConfig config;
  config.texture_paths = {"/nonexistent/deep_ois_missing_photo.jpg"};
  try {
    buildScene(config, Category::kRegular, 1, rig.motion, rig.focalPx(), 2);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/deep_ois_missing_photo.jpg"),
              std::string::npos)
        << e.what();
  }
  const std::string not_an_image = ::testing::TempDir() + "/deep_ois_not_an_image.jpg";
  std::ofstream(not_an_image) << "plain text, not a JPEG\n";
  config.texture_paths = {not_an_image};
  try {
    buildScene(config, Category::kLowTexture, 1, rig.motion, rig.focalPx(), 2);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(not_an_image), std::string::npos) << e.what();
  }
  SceneConfig invalid;
  invalid.near_layer_count = -2;
  EXPECT_THROW(buildScene(invalid, Category::kRegular, 1, rig.motion, rig.focalPx(), 2),
               std::invalid_argument);
}

TEST(BuildScene, IsDeterministicPerSeedAndVariesAcrossSeeds) {
  SKIP_WITHOUT_PHOTOS();
  const Built& a = built(Category::kRegular, 11);
  const Rig rig(11);
  const Scene again =
      buildScene(SceneConfig(), Category::kRegular, 11, rig.motion, rig.focalPx(), 2);
  ASSERT_EQ(a.scene.planes().size(), again.planes().size());
  for (std::size_t i = 0; i < again.planes().size(); ++i) {
    const TexturedPlane& p = a.scene.planes()[i];
    const TexturedPlane& q = again.planes()[i];
    EXPECT_EQ(p.origin_world_m, q.origin_world_m);
    EXPECT_EQ(p.axis_u, q.axis_u);
    EXPECT_EQ(p.width_m, q.width_m);
    ASSERT_EQ(p.texture.size(), q.texture.size());
    EXPECT_EQ(cv::norm(p.texture, q.texture, cv::NORM_INF), 0.0);
  }
  // Another seed: another layout and other crops (a texture of the same size would be a
  // coincidence; compare content when it happens).
  const Built& b = built(Category::kRegular, 12);
  const cv::Mat& ta = a.scene.planes()[0].texture;
  const cv::Mat& tb = b.scene.planes()[0].texture;
  EXPECT_TRUE(ta.size() != tb.size() || cv::norm(ta, tb, cv::NORM_L1) > 0.01 * ta.total());
  EXPECT_NE(a.scene.planes()[1].origin_world_m, b.scene.planes()[1].origin_world_m);
}

TEST(BuildScene, TexturesArePrefilteredLinearRgb) {
  SKIP_WITHOUT_PHOTOS();
  for (Category category :
       {Category::kRegular, Category::kLowTexture, Category::kMovingForeground}) {
    const Built& b = built(category, 3);
    const Eigen::Vector3d centre = b.rig->motion.pose(kStartS).centre_world_m;
    const Eigen::Vector3d axis = b.rig->motion.pose(kStartS).R_world_cam.col(2);
    for (const TexturedPlane& plane : b.scene.planes()) {
      ASSERT_EQ(plane.texture.type(), CV_32FC3);
      double lo = 0.0, hi = 0.0;
      cv::minMaxLoc(plane.texture.reshape(1), &lo, &hi);
      EXPECT_GE(lo, 0.0);
      EXPECT_LE(hi, 1.0);
      EXPECT_LE(plane.texture.total(), 8.0e6);
      // Square texels (not stretched), no finer than half a supersample at the plane's depth.
      const double texel_u = plane.width_m / (plane.texture.cols - 1);
      const double texel_v = plane.height_m / (plane.texture.rows - 1);
      EXPECT_NEAR(texel_u / texel_v, 1.0, 0.02) << toString(category);
      const double depth = (middle(plane) - centre).dot(axis);
      const double half_supersample_m = depth / (b.rig->focalPx() * 2 * 2);
      EXPECT_GT(texel_u, 0.9 * half_supersample_m) << toString(category) << " depth " << depth;
    }
  }
}

TEST(BuildScene, FillsTheViewOverTheWholeMotion) {
  SKIP_WITHOUT_PHOTOS();
  for (Category category : {Category::kRegular, Category::kLowTexture, Category::kLowLight,
                            Category::kMovingForeground}) {
    for (std::uint32_t seed : {3u, 4u}) {
      const Built& b = built(category, seed);
      for (double stamp : stampsOverMotion(12)) {
        const std::vector<int> seen = visiblePlanes(*b.rig, b.scene, stamp, 9);
        EXPECT_EQ(std::count(seen.begin(), seen.end(), -1), 0)
            << toString(category) << " seed " << seed << " at " << stamp << " s";
      }
    }
  }
}

TEST(BuildScene, RegularSceneHasParallaxLayers) {
  SKIP_WITHOUT_PHOTOS();
  const SceneConfig config;
  for (std::uint32_t seed : {3u, 4u, 5u}) {
    const Built& b = built(Category::kRegular, seed);
    const std::vector<TexturedPlane>& planes = b.scene.planes();
    ASSERT_EQ(static_cast<int>(planes.size()), 1 + config.near_layer_count);
    const Eigen::Vector3d centre = b.rig->motion.pose(kStartS).centre_world_m;
    const double background = distanceAlongNormal(planes[0], centre);
    EXPECT_GE(background, config.background_depth_min_m);
    EXPECT_LE(background, config.background_depth_max_m);
    for (std::size_t i = 1; i < planes.size(); ++i) {
      const double depth = middle(planes[i]).x() - centre.x();
      EXPECT_GE(depth, config.near_depth_min_m * 0.95);
      EXPECT_LE(depth, config.near_depth_max_m);
    }
    // The near layers cover a real part of the view, not all of it.
    const std::vector<int> seen = visiblePlanes(*b.rig, b.scene, 0.0, 4);
    const double near_share =
        std::count_if(seen.begin(), seen.end(), [](int p) { return p >= 1; }) /
        static_cast<double>(seen.size());
    EXPECT_GT(near_share, 0.08) << "seed " << seed;
    EXPECT_LT(near_share, 0.7) << "seed " << seed;
  }
}

TEST(BuildScene, MovingObjectCoversTheRequiredShareAndMoves) {
  SKIP_WITHOUT_PHOTOS();
  const SceneConfig config;
  for (std::uint32_t seed : {3u, 4u, 6u}) {
    const Built& b = built(Category::kMovingForeground, seed);
    const Eigen::Vector3d centre = b.rig->motion.pose(kStartS).centre_world_m;
    std::vector<int> moving;
    for (std::size_t i = 0; i < b.scene.planes().size(); ++i) {
      const TexturedPlane& plane = b.scene.planes()[i];
      if (plane.isStatic()) continue;
      moving.push_back(static_cast<int>(i));
      // Sideways (horizontal, across the view) at the configured speed and depth.
      EXPECT_NEAR(plane.velocity_world_m_s.norm(), config.moving_object_speed_m_s, 1e-12);
      EXPECT_NEAR(plane.velocity_world_m_s.z(), 0.0, 1e-12);
      EXPECT_NEAR(std::abs(plane.velocity_world_m_s.normalized().dot(plane.axis_u)), 1.0, 1e-9);
      const double depth = distanceAlongNormal(plane, centre);
      EXPECT_GE(depth, config.moving_object_depth_m - 0.05);
      EXPECT_LE(depth, config.moving_object_depth_m + 0.5);
    }
    ASSERT_FALSE(moving.empty());
    for (double stamp : stampsOverMotion(10)) {
      const std::vector<int> seen = visiblePlanes(*b.rig, b.scene, stamp, 4);
      const double share =
          std::count_if(
              seen.begin(), seen.end(),
              [&](int p) { return std::find(moving.begin(), moving.end(), p) != moving.end(); }) /
          static_cast<double>(seen.size());
      EXPECT_GE(share, config.moving_object_min_coverage)
          << "seed " << seed << " at " << stamp << " s";
      EXPECT_LE(share, 0.8) << "seed " << seed << " at " << stamp
                            << " s: the static scene must show";
    }
  }
}

TEST(BuildScene, LowTextureSceneIsMostlyPlain) {
  SKIP_WITHOUT_PHOTOS();
  for (std::uint32_t seed : {3u, 4u, 7u}) {
    const Built& b = built(Category::kLowTexture, seed);
    // Plane 0 is the sky or wall: nearly uniform, a gentle gradient at most.
    const cv::Mat& plain = b.scene.planes()[0].texture;
    cv::Mat grey, gx, gy;
    cv::cvtColor(plain, grey, cv::COLOR_RGB2GRAY);
    cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
    cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
    EXPECT_LT(cv::norm(gx, cv::NORM_INF), 2e-3);
    EXPECT_LT(cv::norm(gy, cv::NORM_INF), 2e-3);
    const std::vector<int> seen = visiblePlanes(*b.rig, b.scene, 0.5, 4);
    const double plain_share = std::count(seen.begin(), seen.end(), 0) / double(seen.size());
    EXPECT_GT(plain_share, 0.4) << "seed " << seed;
    EXPECT_LT(plain_share, 0.85) << "seed " << seed;
  }
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
