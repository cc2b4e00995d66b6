// Simulator bags end to end, without a roscore: what simulate writes, read back the way a robot's
// recording would be, through the gyro flow core.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>

#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"

namespace deep_ois {
namespace {

std::string configPath(const std::string& category) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/" + category + ".yaml";
}

std::string writeBag(const sim::SimulatorConfig& config, std::uint32_t seed, double duration_s,
                     const std::string& name) {
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  const sim::Simulator simulator(config, seed, duration_s);
  writeSimulationBag(simulator, path, rosbag::compression::Uncompressed, SimulationBagTopics{}, nullptr);
  return path;
}

std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The gyro flow of every pair, computed from the bag's own IMU, tf and camera_info exactly as the
// nodelet does (patch_time centre, time offset 0, linear interpolation).
std::vector<std::vector<Eigen::Matrix3d>> gyroHomographies(const BagSequence& bag, int patches,
                                                           double readout_s) {
  RollingShutterConfig rs;
  rs.patch_count = patches;
  rs.readout_time_s = readout_s;
  rs.imu_to_camera_rotation = *bag.imu_to_camera_rotation;
  const ImuSampleBuffer buffer = bag.imuBuffer();
  std::vector<std::vector<Eigen::Matrix3d>> out;
  for (const FramePairTruth& truth : bag.truths) {
    const auto result = computeRollingShutterHomographies(
        buffer, IntegrationOptions{}, rs, bag.camera->K(), bag.secondsSinceBase(truth.previous_stamp),
        bag.secondsSinceBase(truth.header.stamp));
    EXPECT_TRUE(result.ok()) << result.reason;
    out.push_back(result.homographies);
  }
  return out;
}

TEST(SimulationBag, GyroFlowFromTheBagReproducesTheTrueMotionWithoutOis) {
  sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("RE"));
  config.ois.enabled = false;
  config.motion.translation_rms_m = 0.0;
  config.imu.gyro_noise_density = 0.0;
  config.imu.gyro_bias_random_walk = 0.0;
  config.imu.gyro_initial_bias_rad_s = 0.0;
  const BagSequence bag = readBagSequence(writeBag(config, 3, 1.0, "exact_gyro"));
  ASSERT_TRUE(bag.imu_to_camera_rotation.has_value()) << "no IMU -> camera transform in /tf_static";
  ASSERT_EQ(bag.truths.size(), bag.frame_stamps.size() - 1);
  const auto gyro = gyroHomographies(bag, config.ground_truth.patch_count, config.sensor.readout_time_s);
  double worst_px = 0.0, mean_motion_px = 0.0;
  const int w = config.sensor.width_px, h = config.sensor.height_px;
  for (std::size_t k = 0; k < bag.truths.size(); ++k) {
    const auto truth = unflattenMatrices(bag.truths[k].homographies_without_ois);
    ASSERT_EQ(truth.size(), gyro[k].size());
    for (std::size_t i = 0; i < truth.size(); ++i) {
      // Compare where both send a grid of points of the patch's own rows.
      const double row0 = i * h / double(truth.size()), row1 = (i + 1) * h / double(truth.size()) - 1;
      for (double x : {0.0, w / 2.0, w - 1.0}) {
        for (double y : {row0, row1}) {
          const Eigen::Vector3d p(x, y, 1.0);
          const Eigen::Vector2d expected = (truth[i] * p).hnormalized();
          worst_px = std::max(worst_px, (expected - (gyro[k][i] * p).hnormalized()).norm());
          mean_motion_px += (expected - p.head<2>()).norm();
        }
      }
    }
  }
  mean_motion_px /= bag.truths.size() * gyro[0].size() * 6;
  std::cout << "[ measured ] gyro flow from the bag vs true motion (OIS off, no translation, no IMU noise): "
            << "worst " << worst_px << " px; mean motion " << mean_motion_px << " px\n";
  EXPECT_GT(mean_motion_px, 1.0) << "the motion must be large enough for the check to mean something";
  EXPECT_LT(worst_px, 0.05);
}

// A fisheye (equidistant) recording: the simulator renders through cv::fisheye's model, the bag's
// camera_info says so, and the gyro flow through that model, distort(H_i undistort(p)), lands on
// the annotated correspondences; the same homographies with the fisheye ignored do not.
TEST(SimulationBag, FisheyeRecordingGyroFlowMatchesTheTruth) {
  sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("RE"));
  config.ois.enabled = false;
  config.motion.translation_rms_m = 0.0;
  config.imu.gyro_noise_density = 0.0;
  config.imu.gyro_bias_random_walk = 0.0;
  config.imu.gyro_initial_bias_rad_s = 0.0;
  config.sensor.horizontal_fov_deg = 100.0;
  config.sensor.distortion_model = "equidistant";
  config.sensor.distortion = {-0.05, 0.01, -0.002, 0.0005};  // a wide fisheye-like lens
  ASSERT_EQ(config.validate(), "");
  const BagSequence bag = readBagSequence(writeBag(config, 5, 1.0, "fisheye"));
  ASSERT_TRUE(bag.camera.has_value());
  ASSERT_EQ(bag.camera->distortionModel(), DistortionModel::kEquidistant);
  ASSERT_EQ(bag.camera->coefficients(), config.sensor.distortion);
  ASSERT_TRUE(bag.imu_to_camera_rotation.has_value());
  const auto gyro = gyroHomographies(bag, config.ground_truth.patch_count, config.sensor.readout_time_s);
  const CameraModel pinhole(bag.camera->width(), bag.camera->height(), bag.camera->K());
  double error_px = 0.0, error_ignoring_fisheye_px = 0.0, largest_distortion_px = 0.0;
  int pairs = 0;
  for (std::size_t k = 0; k < bag.truths.size(); ++k) {
    const auto points_a = unflattenPoints(bag.truths[k].points_a), points_b = unflattenPoints(bag.truths[k].points_b);
    if (points_a.empty()) continue;
    error_px += geometryDistance(points_a, points_b, gyro[k], *bag.camera);
    error_ignoring_fisheye_px += geometryDistance(points_a, points_b, gyro[k], pinhole);
    for (const Eigen::Vector2d& p : points_a) {
      largest_distortion_px = std::max(largest_distortion_px, (bag.camera->undistort(p) - p).norm());
    }
    ++pairs;
  }
  ASSERT_GT(pairs, 20);
  error_px /= pairs;
  error_ignoring_fisheye_px /= pairs;
  std::cout << "[ measured ] fisheye recording (equidistant, " << config.sensor.horizontal_fov_deg
            << " deg, annotated points up to " << largest_distortion_px << " px from their undistorted "
            << "place), " << pairs << " pairs: gyro flow geometry distance " << error_px
            << " px; with the fisheye ignored " << error_ignoring_fisheye_px << " px\n";
  EXPECT_GT(largest_distortion_px, 10.0) << "the lens must distort noticeably for the check to mean something";
  EXPECT_LT(error_px, 0.1);
  EXPECT_GT(error_ignoring_fisheye_px, 3.0 * error_px);
}

TEST(SimulationBag, OisMakesTheGyroMissTheAnnotations) {
  sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("RE"));
  const BagSequence with_ois = readBagSequence(writeBag(config, 5, 1.0, "ois_on"));
  config.ois.enabled = false;
  const BagSequence twin = readBagSequence(writeBag(config, 5, 1.0, "ois_off"));
  auto meanError = [&](const BagSequence& bag) {
    const auto gyro = gyroHomographies(bag, config.ground_truth.patch_count, config.sensor.readout_time_s);
    double sum = 0.0;
    for (std::size_t k = 0; k < bag.truths.size(); ++k) {
      sum += geometryDistance(unflattenPoints(bag.truths[k].points_a), unflattenPoints(bag.truths[k].points_b), gyro[k],
                              config.sensor.height_px);
    }
    return sum / bag.truths.size();
  };
  const double ois_px = meanError(with_ois), twin_px = meanError(twin);
  std::cout << "[ measured ] gyro geometry distance: OIS camera " << ois_px << " px, non-OIS twin " << twin_px
            << " px\n";
  EXPECT_GT(ois_px, 2.0 * twin_px);
  for (const auto& truth : with_ois.truths) EXPECT_TRUE(truth.ois_enabled);
  for (const auto& truth : twin.truths) EXPECT_FALSE(truth.ois_enabled);
}

// A generated stabiliser design (ois.design_seed) renders as any module: its lens is in the bag's
// truth, another than the category's own stabiliser's, and its non-OIS twin has none.
TEST(SimulationBag, AGeneratedDesignRendersToABag) {
  sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("RE"));
  config.sensor.width_px = 160;  // small and fast: the lens is what is checked
  config.sensor.height_px = 120;
  const BagSequence module = readBagSequence(writeBag(config, 6, 0.5, "module_design"));
  config.ois.design_seed = 7;
  const BagSequence generated = readBagSequence(writeBag(config, 6, 0.5, "generated_design"));
  config.ois.enabled = false;
  const BagSequence twin = readBagSequence(writeBag(config, 6, 0.5, "generated_design_twin"));
  ASSERT_EQ(generated.truths.size(), module.truths.size());
  ASSERT_FALSE(generated.truths.empty());
  double largest_px = 0.0, difference_px = 0.0;
  for (std::size_t k = 0; k < generated.truths.size(); ++k) {
    EXPECT_TRUE(generated.truths[k].ois_enabled);
    const auto& lens = generated.truths[k].lens_shift_a;
    ASSERT_EQ(lens.size(), module.truths[k].lens_shift_a.size());
    for (std::size_t i = 0; i < lens.size(); ++i) {
      largest_px = std::max(largest_px, std::abs(lens[i]));
      difference_px = std::max(difference_px, std::abs(lens[i] - module.truths[k].lens_shift_a[i]));
    }
    for (double shift : twin.truths[k].lens_shift_a) EXPECT_EQ(0.0, shift);
  }
  std::cout << "[ measured ] generated design 7: lens up to " << largest_px
            << " px, up to " << difference_px << " px from RE's own stabiliser\n";
  EXPECT_GT(largest_px, 0.3);
  EXPECT_GT(difference_px, 0.1);
}

TEST(SimulationBag, SameSeedAndConfigGiveIdenticalBags) {
  const sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("MF"));
  const std::string first = fileBytes(writeBag(config, 9, 0.2, "same_a"));
  const std::string second = fileBytes(writeBag(config, 9, 0.2, "same_b"));
  ASSERT_GT(first.size(), 100000u);
  EXPECT_TRUE(first == second) << "bags of the same seed and config differ";
}

TEST(SimulationBag, FramesStreamBackAsRendered) {
  const sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("LL"));
  const sim::Simulator simulator(config, 4, 0.2);
  const std::string path = ::testing::TempDir() + "/frames.bag";
  writeSimulationBag(simulator, path, rosbag::compression::BZ2, SimulationBagTopics{}, nullptr);
  BagFrameReader reader(path, "/camera/image_raw");
  ASSERT_EQ(reader.frameCount(), static_cast<std::size_t>(simulator.frameCount()));
  BagFrame frame;
  int k = 0;
  while (reader.next(frame)) {
    ASSERT_LT(k, simulator.frameCount());
    EXPECT_EQ(cv::norm(frame.rgb, simulator.renderFrame(k), cv::NORM_INF), 0.0) << "frame " << k;
    EXPECT_EQ(frame.gray.type(), CV_8UC1);
    EXPECT_EQ(frame.frame_id, config.camera_frame_id);
    ++k;
  }
  EXPECT_EQ(k, simulator.frameCount());
  EXPECT_THROW(BagFrameReader(path, "/no/such/topic"), std::runtime_error);
}

TEST(SimulationBag, TruncatedBagGivesAClearError) {
  const sim::SimulatorConfig config = sim::loadSimulatorConfig(configPath("RE"));
  const std::string bytes = fileBytes(writeBag(config, 2, 0.2, "whole"));
  const std::string truncated = ::testing::TempDir() + "/truncated.bag";
  std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  try {
    readBagSequence(truncated);
    FAIL() << "a truncated bag was read without error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(truncated), std::string::npos) << e.what();
  }
  try {
    BagFrameReader reader(truncated, "/camera/image_raw");
    BagFrame frame;
    while (reader.next(frame)) {
    }
    FAIL() << "a truncated bag was streamed without error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(truncated), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deep_ois
