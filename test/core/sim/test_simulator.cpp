// The simulator as a whole: configuration files, determinism, the non-OIS twin, and ground truth
// that agrees with the rendered pixels.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <opencv2/imgproc.hpp>

#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/sim/simulator.h"
#include "test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

std::string configPath(const std::string& category) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/" + category + ".yaml";
}

std::string loadError(const std::string& yaml) {
  const std::string path = ::testing::TempDir() + "/deep_ois_bad_config.yaml";
  std::ofstream(path) << yaml;
  try {
    loadSimulatorConfig(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

TEST(SimulatorConfig, ShippedFilesLoadWithTheirCategory) {
  for (const char* name : {"RE", "LT", "LL", "MF"}) {
    const SimulatorConfig config = loadSimulatorConfig(configPath(name));
    EXPECT_STREQ(toString(config.category), name);
    EXPECT_EQ(config.validate(), "");
    EXPECT_FALSE(config.scene.texture_paths.empty()) << "no photographs found for the scene";
  }
  const SimulatorConfig ll = loadSimulatorConfig(configPath("LL"));
  const SimulatorConfig re = loadSimulatorConfig(configPath("RE"));
  EXPECT_LT(ll.sensor.brightness, 0.2 * re.sensor.brightness);
  EXPECT_GT(ll.sensor.exposure_time_s, re.sensor.exposure_time_s);
}

// Passes when loading `yaml` fails with a message containing `expected`.
::testing::AssertionResult failsWith(const std::string& yaml, const std::string& expected) {
  const std::string error = loadError(yaml);
  if (error.find(expected) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "error '" << error << "' does not contain '" << expected << "'";
}

TEST(SimulatorConfig, OptionalInitialBiasVector) {
  EXPECT_FALSE(loadSimulatorConfig(configPath("RE")).imu.gyro_initial_bias_vector_rad_s.has_value());
  const std::string path = ::testing::TempDir() + "/deep_ois_bias_config.yaml";
  std::ofstream(path) << "imu:\n  gyro_initial_bias_vector_rad_s: [0.001, -0.002, 0.003]\n";
  const SimulatorConfig config = loadSimulatorConfig(path);
  ASSERT_TRUE(config.imu.gyro_initial_bias_vector_rad_s.has_value());
  EXPECT_EQ(*config.imu.gyro_initial_bias_vector_rad_s, Eigen::Vector3d(0.001, -0.002, 0.003));
}

TEST(SimulatorConfig, ErrorsNameTheField) {
  EXPECT_TRUE(failsWith("sensor:\n  widht_px: 360\n", "sensor.widht_px: unknown key"));
  EXPECT_TRUE(failsWith("sensor:\n  width_px: wide\n", "sensor.width_px: has the wrong type"));
  EXPECT_TRUE(failsWith("sensor:\n  width_px: -4\n", "sensor: "));
  EXPECT_TRUE(failsWith("category: XX\n", "category: 'XX' is not one of"));
  EXPECT_TRUE(failsWith("imu:\n  imu_to_camera_rotation: [1, 0, 0]\n", "imu.imu_to_camera_rotation: must hold 9"));
  EXPECT_TRUE(failsWith("bogus: 1\n", "bogus: unknown section"));
  EXPECT_TRUE(failsWith("imu:\n  gyro_initial_bias_vector_rad_s: [0.1, 0.2]\n",
                        "imu.gyro_initial_bias_vector_rad_s: must hold 3 numbers or none"));
  EXPECT_TRUE(failsWith("ground_truth:\n  min_correspondences: 9\n", "ground_truth.min_correspondences"));
}

TEST(Simulator, SameSeedSameSequenceAndTwinSharesEverythingButOis) {
  const SimulatorConfig config = loadSimulatorConfig(configPath("RE"));
  const Simulator first(config, 7, 0.3);
  const Simulator again(config, 7, 0.3);
  EXPECT_EQ(cv::norm(first.renderFrame(4), again.renderFrame(4), cv::NORM_INF), 0.0);
  ASSERT_EQ(first.imu().size(), again.imu().size());
  EXPECT_EQ(first.imu()[10].angular_velocity_rad_s, again.imu()[10].angular_velocity_rad_s);
  EXPECT_EQ(first.pairTruth(3).points_b_px, again.pairTruth(3).points_b_px);

  const Simulator other_seed(config, 8, 0.3);
  EXPECT_GT(cv::norm(first.renderFrame(4), other_seed.renderFrame(4), cv::NORM_L1), 0.0);

  SimulatorConfig twin_config = config;
  twin_config.ois.enabled = false;
  const Simulator twin(twin_config, 7, 0.3);
  EXPECT_EQ(first.imu()[10].angular_velocity_rad_s, twin.imu()[10].angular_velocity_rad_s);
  const FramePairTruth with = first.pairTruth(5), without = twin.pairTruth(5);
  for (std::size_t i = 0; i < with.rotations_b_a.size(); ++i) {
    EXPECT_MATRIX_NEAR(with.homographies_without_ois[i], without.homographies_without_ois[i], 1e-12);
    EXPECT_MATRIX_NEAR(without.homographies_without_ois[i], without.homographies_with_ois[i], 1e-12);
  }
  EXPECT_GT(cv::norm(first.renderFrame(5), twin.renderFrame(5), cv::NORM_L1), 0.0);
}

// The annotated correspondences are where the rendered pixels really went: KLT, started at each
// annotated point of frame a, lands on its annotated partner in frame b.
TEST(Simulator, KltOnRenderedFramesMatchesAnnotatedCorrespondences) {
  const SimulatorConfig config = loadSimulatorConfig(configPath("RE"));
  const Simulator simulator(config, 11, 0.6);
  std::vector<double> errors;
  KltOptions klt;
  klt.max_forward_backward_error_px = 0.3;
  for (int k = 1; k < simulator.frameCount(); ++k) {
    const FramePairTruth truth = simulator.pairTruth(k);
    ASSERT_GE(truth.points_a_px.size(), static_cast<std::size_t>(config.ground_truth.min_correspondences))
        << "pair " << k;
    cv::Mat gray_a, gray_b;
    cv::cvtColor(simulator.renderFrame(k - 1), gray_a, cv::COLOR_RGB2GRAY);
    cv::cvtColor(simulator.renderFrame(k), gray_b, cv::COLOR_RGB2GRAY);
    std::vector<cv::Point2f> starts;
    for (const auto& p : truth.points_a_px) starts.emplace_back(p.x(), p.y());
    std::vector<TrackStatus> status;
    const std::vector<FeatureMatch> matches = trackFeatures(gray_a, gray_b, starts, klt, &status);
    std::size_t m = 0;
    for (std::size_t j = 0; j < starts.size(); ++j) {
      if (status[j] != TrackStatus::kTracked) continue;
      const FeatureMatch& match = matches[m++];
      errors.push_back((Eigen::Vector2d(match.point_b_px.x, match.point_b_px.y) - truth.points_b_px[j]).norm());
    }
  }
  ASSERT_GT(errors.size(), 60u) << "too few annotated points survived KLT's checks";
  const double median_px = median(errors);
  std::cout << "[ measured ] KLT vs annotated correspondences on " << errors.size()
            << " points: median " << median_px << " px\n";
  EXPECT_LT(median_px, 0.3);
}

// The problem the network solves: with OIS on, the exact rotation (what a perfect gyro predicts)
// misses the annotated points by much more than on the non-OIS twin.
TEST(Simulator, OisBreaksTheGyroPrediction) {
  SimulatorConfig config = loadSimulatorConfig(configPath("RE"));
  const Simulator ois(config, 21, 1.0);
  config.ois.enabled = false;
  const Simulator twin(config, 21, 1.0);
  double error_ois = 0.0, error_twin = 0.0, error_with_ois_truth = 0.0;
  for (int k = 1; k < ois.frameCount(); ++k) {
    const FramePairTruth a = ois.pairTruth(k), b = twin.pairTruth(k);
    const int h = config.sensor.height_px;
    error_ois += geometryDistance(a.points_a_px, a.points_b_px, a.homographies_without_ois, h);
    error_twin += geometryDistance(b.points_a_px, b.points_b_px, b.homographies_without_ois, h);
    // The truth with OIS explains the OIS frames up to parallax: the camera translates by about
    // 1 cm, and points on boards 1.5-2 m away move up to ~1.5 px per frame from it.
    const double with_ois = geometryDistance(a.points_a_px, a.points_b_px, a.homographies_with_ois, h);
    EXPECT_LT(with_ois, 2.0) << "pair " << k;
    error_with_ois_truth += with_ois;
  }
  const int pairs = ois.frameCount() - 1;
  error_ois /= pairs;
  error_twin /= pairs;
  error_with_ois_truth /= pairs;
  std::cout << "[ measured ] exact-rotation prediction error: OIS " << error_ois << " px, non-OIS twin "
            << error_twin << " px; rotation with the true lens shift " << error_with_ois_truth << " px\n";
  EXPECT_GT(error_ois, 2.0 * error_twin);
  // Parallax alone is what the OIS-aware truth leaves, as the twin's exact rotation does.
  EXPECT_LT(error_with_ois_truth, 1.5 * error_twin);
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
