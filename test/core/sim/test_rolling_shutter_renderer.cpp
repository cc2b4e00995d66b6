// The simulated camera and its renderer: rolling-shutter geometry with the OIS lens shift and
// distortion (projection round trips), rendered pixels that agree with that geometry (per-pixel
// ray casts, checkerboard corners), sensor photometry and noise, and the look of the categories.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <opencv2/imgproc.hpp>

#include "deep_ois/core/sim/rolling_shutter_renderer.h"
#include "test_helpers.h"
#include "sim_test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kStartS = -0.25;
constexpr double kEndS = 1.5;
// A phone lens: barrel distortion, one-to-one well beyond the image corners.
const std::vector<double> kPhoneDistortion{-0.12, 0.03, 0.0005, -0.0003, 0.0};

// Hand-held motion (the default shake and pans), the default OIS, a camera.
struct Rig : test::Rig {
  explicit Rig(const SensorConfig& sensor_config, std::uint32_t seed = 7,
               const OisConfig& ois_config = OisConfig())
      : test::Rig(kStartS, kEndS, sensor_config, seed, ois_config) {}
};

SensorConfig distortedSensor() {
  SensorConfig sensor;
  sensor.distortion = kPhoneDistortion;
  return sensor;
}

SensorConfig noiseFree(SensorConfig sensor) {
  sensor.add_noise = false;
  return sensor;
}

bool photosInstalled() { return !defaultTexturePaths().empty(); }

#define SKIP_WITHOUT_PHOTOS()                               \
  if (!photosInstalled())                                   \
  GTEST_SKIP() << "mate-backgrounds is not installed (run " \
                  "scripts/install_deps.sh)"

// A large fronto-parallel plane at `depth_m` in front of the start pose, centred on the view.
TexturedPlane wall(double depth_m, double width_m, double height_m, cv::Mat texture) {
  TexturedPlane plane;
  plane.origin_world_m = Eigen::Vector3d(depth_m, 0.5 * width_m, 0.5 * height_m);
  plane.axis_u = -Eigen::Vector3d::UnitY();
  plane.axis_v = -Eigen::Vector3d::UnitZ();
  plane.width_m = width_m;
  plane.height_m = height_m;
  plane.texture = std::move(texture);
  return plane;
}

// 8-bit code of a linear value, as the sensor writes it.
double encoded(double linear) { return 255.0 * std::pow(std::clamp(linear, 0.0, 1.0), 1.0 / 2.2); }

cv::Mat toLinear(const cv::Mat& rgb8) {
  cv::Mat linear;
  rgb8.convertTo(linear, CV_32FC3, 1.0 / 255.0);
  cv::pow(linear, 2.2, linear);
  return linear;
}

cv::Mat grey(const cv::Mat& rgb8) {
  cv::Mat out;
  cv::cvtColor(rgb8, out, cv::COLOR_RGB2GRAY);
  return out;
}

// Sobel gradient magnitude, 8-bit units per pixel.
cv::Mat gradientMagnitude(const cv::Mat& grey8) {
  cv::Mat gx, gy, magnitude;
  cv::Sobel(grey8, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(grey8, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  cv::magnitude(gx, gy, magnitude);
  return magnitude;
}

TEST(SensorConfig, ValidateNamesTheBadField) {
  EXPECT_EQ(SensorConfig().validate(), "");
  auto problem = [](auto edit) {
    SensorConfig sensor;
    edit(sensor);
    return sensor.validate();
  };
  EXPECT_NE(problem([](SensorConfig& s) { s.width_px = 0; }).find("width_px"), std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.horizontal_fov_deg = 190.0; }).find("horizontal_fov"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.readout_time_s = 0.05; }).find("readout_time_s"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.exposure_time_s = 0.0; }).find("exposure_time_s"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.distortion.assign(6, 0.0); }).find("distortion"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.supersampling = 0; }).find("supersampling"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.exposure_samples = 0; }).find("exposure_samples"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.brightness = -1.0; }).find("brightness"),
            std::string::npos);
  EXPECT_NE(problem([](SensorConfig& s) { s.read_noise_electrons = -1.0; }).find("read_noise"),
            std::string::npos);
}

TEST(SimCamera, NominalIntrinsicsRowTimesAndLensShift) {
  const Rig rig(distortedSensor());
  const CameraModel& nominal = rig.camera.nominal();
  EXPECT_NEAR(nominal.K()(0, 0), 180.0 / std::tan(35.0 * M_PI / 180.0), 1e-9);
  EXPECT_EQ(nominal.K()(0, 0), nominal.K()(1, 1));
  EXPECT_EQ(nominal.K()(0, 2), 179.5);
  EXPECT_EQ(nominal.K()(1, 2), 134.5);
  EXPECT_TRUE(nominal.hasDistortion());
  EXPECT_DOUBLE_EQ(rig.camera.rowTime(1.0, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(rig.camera.rowTime(1.0, 135.0), 1.0 + 0.011);
  EXPECT_DOUBLE_EQ(rig.camera.rowTime(1.0, 270.0), 1.0 + 0.022);
  double largest_shift = 0.0;
  for (double t = 0.0; t < 1.0; t += 0.01) {
    const Eigen::Vector2d shift = rig.ois.lensShift(t);
    Eigen::Matrix3d expected = nominal.K();
    expected(0, 2) += shift.x();
    expected(1, 2) += shift.y();
    EXPECT_MATRIX_NEAR(expected, rig.camera.intrinsicsAt(t), 0.0);
    largest_shift = std::max(largest_shift, shift.norm());
  }
  EXPECT_GT(largest_shift, 0.5) << "the OIS should move the lens under the default shake";
}

TEST(SimCamera, ProjectInvertsRayDirectionWithOisAndDistortion) {
  const Rig rig(distortedSensor());
  for (double t : {0.0, 0.137, 0.61}) {
    for (const Eigen::Vector2d& pixel :
         {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(359.4, 269.4), Eigen::Vector2d(12.3, 250.8),
          Eigen::Vector2d(180.0, 135.0)}) {
      const Eigen::Vector3d d = rig.camera.rayDirectionWorld(pixel, t);
      EXPECT_NEAR(d.norm(), 1.0, 1e-12);
      Eigen::Vector2d back;
      ASSERT_TRUE(rig.camera.project(rig.motion.pose(t).centre_world_m + 6.5 * d, t, &back));
      EXPECT_MATRIX_NEAR(pixel, back, 1e-8);
    }
  }
  // The lens shift moves the distortion centre with the lens: a pure shift of the principal
  // point moves every raw pixel by the same amount.
  const Eigen::Vector3d X = rig.motion.pose(0.3).centre_world_m +
                            5.0 * rig.camera.rayDirectionWorld(Eigen::Vector2d(30.0, 40.0), 0.3);
  Eigen::Vector2d shifted;
  ASSERT_TRUE(rig.camera.project(X, 0.3, &shifted));
  const CameraPose pose = rig.motion.pose(0.3);
  const Eigen::Vector3d X_cam = pose.R_world_cam.transpose() * (X - pose.centre_world_m);
  const Eigen::Vector2d unshifted =
      rig.camera.nominal().distort((rig.camera.nominal().K() * X_cam).hnormalized());
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(unshifted + rig.ois.lensShift(0.3)), shifted, 1e-9);
}

TEST(SimCamera, RollingShutterProjectionRoundTripsBelowMicroPixel) {
  for (const SensorConfig& sensor : {SensorConfig(), distortedSensor()}) {
    const Rig rig(sensor);
    double worst = 0.0;
    for (double stamp : {0.0, 0.2331, 0.9}) {
      for (double y = -0.45; y < 270.0; y += 26.9) {
        for (double x = -0.45; x < 360.0; x += 35.9) {
          const Eigen::Vector2d pixel(x, y);
          const double t = rig.camera.rowTime(stamp, y);
          const Eigen::Vector3d X = rig.motion.pose(t).centre_world_m +
                                    (2.0 + 0.1 * x) * rig.camera.rayDirectionWorld(pixel, t);
          Eigen::Vector2d projected;
          double t_projected = 0.0;
          ASSERT_TRUE(rig.camera.projectRollingShutter(X, stamp, &projected, &t_projected))
              << x << "," << y << " at " << stamp;
          worst = std::max(worst, (projected - pixel).norm());
          EXPECT_NEAR(t_projected, t, 1e-9);
        }
      }
    }
    EXPECT_LT(worst, 1e-6);
  }
}

TEST(SimCamera, RollingShutterProjectionRejectsWhatTheFrameDoesNotSee) {
  const Rig rig(distortedSensor());
  const CameraPose pose = rig.motion.pose(0.0);
  Eigen::Vector2d pixel;
  // Behind the camera.
  EXPECT_FALSE(rig.camera.projectRollingShutter(pose.centre_world_m - 3.0 * pose.R_world_cam.col(2),
                                                0.0, &pixel));
  // In front but outside the image (45 degrees to the side: the half-width is 35).
  const Eigen::Vector3d side = pose.R_world_cam * Eigen::Vector3d(1.0, 0.0, 1.0);
  EXPECT_FALSE(rig.camera.projectRollingShutter(pose.centre_world_m + 4.0 * side, 0.0, &pixel));
  // A strong barrel lens (k1 only) is one-to-one out to 46 degrees; its polynomial folds a point
  // 58 degrees off axis back into the image, which a real lens never shows.
  SensorConfig barrel;
  barrel.distortion = {-0.3, 0.0, 0.0, 0.0, 0.0};
  const Rig fold(barrel);
  const CameraPose fold_pose = fold.motion.pose(0.0);
  const Eigen::Vector3d far_side(1.6, 0.0, 1.0);
  const Eigen::Vector2d folded =
      fold.camera.nominal().distort((fold.camera.nominal().K() * far_side).hnormalized());
  ASSERT_LT(folded.x(), 359.0) << "the polynomial does fold this point into the image";
  const Eigen::Vector3d X = fold_pose.centre_world_m + 3.0 * (fold_pose.R_world_cam * far_side);
  EXPECT_FALSE(fold.camera.project(X, 0.0, &pixel));
  EXPECT_FALSE(fold.camera.projectRollingShutter(X, 0.0, &pixel));
  // While points inside the view still project.
  const Eigen::Vector3d inside =
      fold_pose.centre_world_m + 3.0 * (fold_pose.R_world_cam * Eigen::Vector3d(0.6, 0.4, 1.0));
  EXPECT_TRUE(fold.camera.projectRollingShutter(inside, 0.0, &pixel));
}

// Every pixel the renderer writes (one sample per pixel and per row time, no noise) is the
// radiance the scene shows along the camera's ray for that pixel at that row's time.
TEST(RollingShutterRenderer, PixelsAreTheSceneAlongTheCameraRays) {
  SKIP_WITHOUT_PHOTOS();
  SensorConfig sensor = noiseFree(distortedSensor());
  sensor.supersampling = 1;
  sensor.exposure_samples = 1;
  const Rig rig(sensor);
  const Scene scene =
      buildScene(SceneConfig(), Category::kMovingForeground, 5, rig.motion, rig.focalPx(), 1);
  const RollingShutterRenderer renderer(scene, rig.camera);
  const double stamp = 0.4;
  const cv::Mat image = renderer.render(stamp, 12, 1);
  ASSERT_EQ(image.type(), CV_8UC3);
  ASSERT_EQ(image.size(), cv::Size(360, 270));
  auto hitAt = [&](const Eigen::Vector2d& pixel, SceneHit* hit) {
    const double t = rig.camera.rowTime(stamp, pixel.y());
    return scene.intersect(rig.motion.pose(t).centre_world_m,
                           rig.camera.rayDirectionWorld(pixel, t), t, hit);
  };
  int compared = 0, moving = 0;
  double worst = 0.0;
  for (int y = 1; y < 270; y += 3) {
    for (int x = 1; x < 360; x += 3) {
      SceneHit hit;
      ASSERT_TRUE(hitAt(Eigen::Vector2d(x, y), &hit));
      // Skip pixels on an occlusion edge, where a rounding error may pick the other plane.
      bool edge = false;
      for (const Eigen::Vector2d& offset :
           {Eigen::Vector2d(-0.5, 0.0), Eigen::Vector2d(0.5, 0.0), Eigen::Vector2d(0.0, -0.5),
            Eigen::Vector2d(0.0, 0.5)}) {
        SceneHit neighbour;
        edge |= !hitAt(Eigen::Vector2d(x, y) + offset, &neighbour) ||
                neighbour.plane_index != hit.plane_index;
      }
      if (edge) continue;
      ++compared;
      moving += hit.is_static ? 0 : 1;
      const cv::Vec3b pixel = image.at<cv::Vec3b>(y, x);
      for (int ch = 0; ch < 3; ++ch) {
        worst = std::max(worst, std::abs(pixel[ch] - encoded(hit.radiance[ch])));
      }
    }
  }
  EXPECT_GT(compared, 9000);
  EXPECT_GT(moving, 2000) << "the moving object is rendered where it is";
  EXPECT_LE(worst, 1.0) << "8-bit rounding only";
}

// Corners of a checkerboard on a plane, located in the rendered image by cv::cornerSubPix,
// against the exact rolling-shutter projection of the same corners (hand-held motion, motion
// blur, OIS lens shift, lens distortion, anti-aliasing all on). The squares' edges are blurred
// by about a pixel, as a lens does: cornerSubPix alone is biased by up to 0.08 px on razor-sharp
// corners, whatever the renderer.
TEST(RollingShutterRenderer, CheckerboardCornersLandOnTheirProjection) {
  const Rig rig(noiseFree(distortedSensor()));
  constexpr int kSquareTexels = 40;   // half a pixel per texel at 3 m
  constexpr double kSquareM = 0.233;  // about 20 px at 3 m
  constexpr double kDepthM = 3.0;
  const int cols = 34 * kSquareTexels, rows = 27 * kSquareTexels;
  cv::Mat texture(rows, cols, CV_32FC3);
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < cols; ++i) {
      // Square edges fall half-way between texels (bilinear sampling is symmetric about them).
      const bool bright = (i / kSquareTexels + j / kSquareTexels) % 2 == 0;
      texture.at<cv::Vec3f>(j, i) = cv::Vec3f::all(bright ? 0.6f : 0.05f);
    }
  }
  cv::GaussianBlur(texture, texture, cv::Size(), 2.0);  // sigma = 1 px
  const double texel_m = kSquareM / kSquareTexels;
  const TexturedPlane plane = wall(kDepthM, (cols - 1) * texel_m, (rows - 1) * texel_m, texture);
  const Scene scene({plane});
  const RollingShutterRenderer renderer(scene, rig.camera);

  for (double stamp : {0.1, 0.7}) {
    const cv::Mat image = grey(renderer.render(stamp, 0, 0));
    std::vector<cv::Point2f> found;
    std::vector<Eigen::Vector2d> expected;
    for (int m = 1; m * kSquareTexels < rows; ++m) {
      for (int k = 1; k * kSquareTexels < cols; ++k) {
        const Eigen::Vector3d corner = plane.origin_world_m +
                                       (k * kSquareTexels - 0.5) * texel_m * plane.axis_u +
                                       (m * kSquareTexels - 0.5) * texel_m * plane.axis_v;
        Eigen::Vector2d pixel;
        if (!rig.camera.projectRollingShutter(corner, stamp, &pixel)) continue;
        if (pixel.x() < 14 || pixel.y() < 14 || pixel.x() > 345 || pixel.y() > 255) continue;
        expected.push_back(pixel);
        found.emplace_back(std::round(pixel.x()), std::round(pixel.y()));
      }
    }
    ASSERT_GT(expected.size(), 150u);
    cv::cornerSubPix(image, found, cv::Size(6, 6), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
    double worst = 0.0, sum = 0.0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const double error = (Eigen::Vector2d(found[i].x, found[i].y) - expected[i]).norm();
      worst = std::max(worst, error);
      sum += error;
    }
    EXPECT_LT(worst, 0.1) << "at " << stamp << " s";
    EXPECT_LT(sum / expected.size(), 0.03) << "at " << stamp << " s";
  }
}

TEST(RollingShutterRenderer, FramesAreReproducibleAndNoiseIsSeeded) {
  SKIP_WITHOUT_PHOTOS();
  const Rig rig{SensorConfig()};
  const Scene scene =
      buildScene(SceneConfig(), Category::kRegular, 8, rig.motion, rig.focalPx(), 2);
  const RollingShutterRenderer renderer(scene, rig.camera);
  const cv::Mat a = renderer.render(0.3, 9, 4);
  EXPECT_EQ(cv::norm(a, renderer.render(0.3, 9, 4), cv::NORM_INF), 0.0);
  // The same instant with another frame index or noise seed: other noise, same picture.
  for (const cv::Mat& other : {renderer.render(0.3, 10, 4), renderer.render(0.3, 9, 5)}) {
    cv::Mat difference;
    cv::absdiff(a, other, difference);
    EXPECT_GT(cv::countNonZero(difference.reshape(1)), 0.3 * difference.total() * 3);
    EXPECT_LT(cv::mean(difference)[0], 4.0);
  }
  // Without noise the seeds do not matter.
  const Rig quiet_rig{noiseFree(SensorConfig())};
  const RollingShutterRenderer quiet(scene, quiet_rig.camera);
  const cv::Mat clean = quiet.render(0.3, 9, 4);
  EXPECT_EQ(cv::norm(clean, quiet.render(0.3, 10, 5), cv::NORM_INF), 0.0);
  cv::Mat difference;
  cv::absdiff(a, clean, difference);
  EXPECT_GT(cv::countNonZero(difference.reshape(1)), 0.3 * difference.total() * 3);
}

// A uniform grey wall: the sensor's shot and read noise, through the gamma curve, has the
// spread the photometric model predicts, independent between pixels and channels.
TEST(RollingShutterRenderer, NoiseFollowsThePhotometricModel) {
  constexpr double kRadiance = 0.2;
  const Scene scene({wall(5.0, 20.0, 15.0, cv::Mat(2, 2, CV_32FC3, cv::Scalar::all(kRadiance)))});
  for (double brightness : {1.0, 0.25}) {
    SensorConfig sensor;
    sensor.brightness = brightness;
    const Rig rig(sensor);
    const RollingShutterRenderer renderer(scene, rig.camera);
    const cv::Mat image = renderer.render(0.2, 3, 11);
    const double level = kRadiance * brightness;
    const double electrons = level * sensor.full_well_electrons;
    const double sigma_linear = std::sqrt(electrons + std::pow(sensor.read_noise_electrons, 2)) /
                                sensor.full_well_electrons;
    const double slope = 255.0 / 2.2 * std::pow(level, 1.0 / 2.2 - 1.0);  // DN per linear unit
    const double predicted = std::sqrt(std::pow(slope * sigma_linear, 2) + 1.0 / 12.0);
    cv::Scalar mean, spread;
    cv::meanStdDev(image, mean, spread);
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(mean[ch], encoded(level), 0.3) << "brightness " << brightness;
      EXPECT_NEAR(spread[ch], predicted, 0.07 * predicted) << "brightness " << brightness;
    }
    // Independent neighbours and channels.
    cv::Mat values;
    image.convertTo(values, CV_64FC3);
    values -= mean;
    std::vector<cv::Mat> channels;
    cv::split(values, channels);
    const double variance = spread[0] * spread[0];
    const double horizontal =
        cv::mean(channels[0].colRange(0, 359).mul(channels[0].colRange(1, 360)))[0] / variance;
    const double vertical =
        cv::mean(channels[0].rowRange(0, 269).mul(channels[0].rowRange(1, 270)))[0] / variance;
    const double across = cv::mean(channels[0].mul(channels[1]))[0] / (spread[0] * spread[1]);
    EXPECT_LT(std::abs(horizontal), 0.03);
    EXPECT_LT(std::abs(vertical), 0.03);
    EXPECT_LT(std::abs(across), 0.03);
  }
  // No noise: every pixel is the same exact code.
  const Rig quiet(noiseFree(SensorConfig()));
  const cv::Mat clean = RollingShutterRenderer(scene, quiet.camera).render(0.2, 3, 11);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(clean.reshape(1), &lo, &hi);
  EXPECT_EQ(lo, hi);
  EXPECT_EQ(lo, std::round(encoded(kRadiance)));
}

TEST(RollingShutterRenderer, LowLightIsDarkerAndNoisier) {
  SKIP_WITHOUT_PHOTOS();
  SensorConfig regular;
  SensorConfig low_light;
  low_light.brightness = 0.06;
  low_light.exposure_time_s = 0.025;
  low_light.read_noise_electrons = 4.0;
  const Rig rig(regular);
  const Scene scene =
      buildScene(SceneConfig(), Category::kLowLight, 5, rig.motion, rig.focalPx(), 2);
  // Signal: mean linear level; noise: spread of (noisy - noise-free) in linear light.
  auto measure = [&](const SensorConfig& sensor, double* mean_dn, double* snr) {
    const Rig noisy_rig(sensor), clean_rig(noiseFree(sensor));
    const cv::Mat noisy = RollingShutterRenderer(scene, noisy_rig.camera).render(0.5, 15, 2);
    const cv::Mat clean = RollingShutterRenderer(scene, clean_rig.camera).render(0.5, 15, 2);
    *mean_dn = cv::mean(grey(noisy))[0];
    cv::Scalar mean, spread;
    cv::meanStdDev(toLinear(noisy) - toLinear(clean), mean, spread);
    *snr = cv::mean(toLinear(clean))[1] / spread[1];
  };
  double regular_dn = 0.0, regular_snr = 0.0, dark_dn = 0.0, dark_snr = 0.0;
  measure(regular, &regular_dn, &regular_snr);
  measure(low_light, &dark_dn, &dark_snr);
  EXPECT_LT(dark_dn, 0.5 * regular_dn);
  EXPECT_GT(dark_dn, 5.0) << "dark, not black";
  EXPECT_LT(dark_snr, 0.5 * regular_snr);
}

TEST(RollingShutterRenderer, LowTextureFramesAreMostlyFlatButTrackable) {
  SKIP_WITHOUT_PHOTOS();
  const Rig rig(noiseFree(SensorConfig()));
  for (std::uint32_t seed : {3u, 4u, 7u}) {
    const Scene scene =
        buildScene(SceneConfig(), Category::kLowTexture, seed, rig.motion, rig.focalPx(), 2);
    const cv::Mat image = grey(RollingShutterRenderer(scene, rig.camera).render(0.6, 18, 1));
    const cv::Mat gradient = gradientMagnitude(image);
    const double flat = cv::countNonZero(gradient < 1.0) / static_cast<double>(gradient.total());
    EXPECT_GT(flat, 0.4) << "seed " << seed;
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(image, corners, 300, 0.01, 6.0);
    EXPECT_GE(corners.size(), 20u) << "seed " << seed << ": the textured part must have points";
  }
  // A regular scene, for contrast, is textured nearly everywhere.
  const Scene regular =
      buildScene(SceneConfig(), Category::kRegular, 3, rig.motion, rig.focalPx(), 2);
  const cv::Mat gradient =
      gradientMagnitude(grey(RollingShutterRenderer(regular, rig.camera).render(0.6, 18, 1)));
  EXPECT_LT(cv::countNonZero(gradient < 1.0) / static_cast<double>(gradient.total()), 0.4);
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
