// The offline Fundamental Mixtures job on simulator bags, without a roscore: one record per frame
// pair, targets close to the simulator's true OIS-camera motion, and a broken input that costs
// only itself.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>

#include "deep_ois/TrainingPair.h"
#include "deep_ois/core/geometry_distance.h"
#include "deep_ois/ros/bag_sequence.h"
#include "deep_ois/ros/conversions.h"
#include "deep_ois/ros/fundamental_mixtures_offline.h"
#include "deep_ois/ros/simulation_bag_writer.h"

namespace deep_ois {
namespace {

std::string sourcePath(const std::string& relative) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/" + relative;
}

std::string writeBag(std::uint32_t seed, double duration_s, const std::string& name) {
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  const sim::Simulator simulator(sim::loadSimulatorConfig(sourcePath("config/simulator/RE.yaml")),
                                 seed, duration_s);
  writeSimulationBag(simulator, path, rosbag::compression::Uncompressed, SimulationBagTopics{},
                     nullptr);
  return path;
}

std::string writeTruncatedBag(const std::string& name) {
  const std::string whole = writeBag(12, 0.2, name + "_whole");
  std::ifstream in(whole, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  std::ofstream(path, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  return path;
}

FundamentalMixturesOfflineOptions optionsFor(const std::vector<std::string>& bags,
                                             const std::string& out) {
  FundamentalMixturesOfflineOptions options;
  options.bags = bags;
  options.output_path = ::testing::TempDir() + "/" + out + ".bag";
  options.gyro = loadGyroFlowParameters(YamlParameters(sourcePath("config/gyro_flow.yaml")));
  options.show_progress = false;
  return options;
}

std::vector<TrainingPair> readRecords(const FundamentalMixturesOfflineOptions& options) {
  rosbag::Bag bag(options.output_path, rosbag::bagmode::Read);
  std::vector<TrainingPair> records;
  for (const rosbag::MessageInstance& m :
       rosbag::View(bag, rosbag::TopicQuery(options.output_topic))) {
    const TrainingPair::ConstPtr record = m.instantiate<TrainingPair>();
    if (record) records.push_back(*record);
  }
  return records;
}

// Mean distance, over the four corners of patch i's rows, between where two homographies send
// them. Pixels.
double patchCornerDifference(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b, int patch,
                             int patches, int width, int height) {
  const double row0 = patch * height / double(patches),
               row1 = (patch + 1) * height / double(patches) - 1;
  double sum = 0.0;
  for (double x : {0.0, width - 1.0}) {
    for (double y : {row0, row1}) {
      const Eigen::Vector3d p(x, y, 1.0);
      sum += ((a * p).hnormalized() - (b * p).hnormalized()).norm();
    }
  }
  return sum / 4.0;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

TEST(FundamentalMixturesOffline, TargetsMatchTheTrueMotionAndABrokenBagCostsOnlyItself) {
  const std::string good = writeBag(7, 0.5, "fm_good");
  const std::string truncated = writeTruncatedBag("fm_truncated");
  const FundamentalMixturesOfflineOptions options = optionsFor({good, truncated}, "fm_train");
  const FundamentalMixturesSummary summary = FundamentalMixturesOffline(options).run();
  std::cout << "[ measured ] " << summary.text();

  const BagSequence truth_bag = readBagSequence(good);
  const std::size_t pairs = truth_bag.frame_stamps.size() - 1;
  ASSERT_GE(pairs, 10u);
  ASSERT_EQ(summary.bag_errors.size(), 1u);
  EXPECT_NE(summary.bag_errors[0].find(truncated), std::string::npos) << summary.bag_errors[0];
  EXPECT_FALSE(summary.interrupted);
  EXPECT_EQ(summary.pairs_done, pairs);
  EXPECT_EQ(summary.accepted + summary.rejected, summary.pairs_done);

  const std::vector<TrainingPair> records = readRecords(options);
  ASSERT_EQ(records.size(), pairs)
      << "one record per pair of the good bag, none from the broken one";
  std::map<ros::Time, const FramePairTruth*> truth_at;
  for (const FramePairTruth& truth : truth_bag.truths) truth_at[truth.header.stamp] = &truth;

  std::vector<double> target_px, gyro_px;
  double target_distance_px = 0.0, gyro_distance_px = 0.0;  // the paper's metric, annotated points
  std::map<std::string, int> models;
  std::size_t accepted = 0;
  for (const TrainingPair& record : records) {
    EXPECT_EQ(record.source_bag, good);
    const std::size_t values = 9 * record.patch_count;
    EXPECT_EQ(record.gyro_homographies.size(), values) << "the simulator's IMU covers every pair";
    if (!record.accepted) {
      EXPECT_TRUE(record.target_homographies.empty());
      EXPECT_FALSE(record.rejection_reason.empty());
      continue;
    }
    ++accepted;
    ASSERT_EQ(record.target_homographies.size(), values);
    EXPECT_TRUE(record.rejection_reason.empty());
    EXPECT_EQ(record.patch_inlier_counts.size(), record.patch_count);
    EXPECT_LE(record.inlier_count, record.match_count);
    const auto found = truth_at.find(record.header.stamp);
    ASSERT_NE(found, truth_at.end()) << "no truth for the pair ending at " << record.header.stamp;
    const FramePairTruth& truth = *found->second;
    ASSERT_EQ(truth.patch_count, record.patch_count);
    ASSERT_EQ(truth.previous_stamp, record.previous_stamp);
    ++models[record.model];
    const auto points_a = unflattenPoints(truth.points_a), points_b = unflattenPoints(truth.points_b);
    target_distance_px += geometryDistance(
        points_a, points_b, unflattenMatrices(record.target_homographies), record.image_height);
    gyro_distance_px += geometryDistance(
        points_a, points_b, unflattenMatrices(record.gyro_homographies), record.image_height);
    for (std::size_t i = 0; i < record.patch_count; ++i) {
      const Eigen::Matrix3d expected = rowMajorToMatrix(&truth.homographies_with_ois[9 * i]);
      target_px.push_back(
          patchCornerDifference(rowMajorToMatrix(&record.target_homographies[9 * i]), expected, i,
                                record.patch_count, record.image_width, record.image_height));
      gyro_px.push_back(patchCornerDifference(rowMajorToMatrix(&record.gyro_homographies[9 * i]),
                                              expected, i, record.patch_count, record.image_width,
                                              record.image_height));
    }
  }
  EXPECT_EQ(accepted, summary.accepted);
  std::cout
      << "[ measured ] " << accepted << "/" << records.size()
      << " pairs accepted; median patch-corner difference to the true OIS-camera motion: target "
      << median(target_px) << " px, uncompensated gyro " << median(gyro_px)
      << " px; mean geometry distance on the annotated points: target "
      << target_distance_px / accepted << " px, gyro " << gyro_distance_px / accepted
      << " px; models:";
  for (const auto& [model, count] : models) std::cout << " " << model << " " << count;
  std::cout << "\n";
  EXPECT_GE(accepted * 4, records.size() * 3)
      << "a textured RE scene should give most pairs a target";
  // Measured (seed 7, 0.5 s, RE): target 1.21 px median corner difference, gyro 1.98 px;
  // geometry distance 1.55 px vs 1.98 px. The target is not exact: the translation parallax of
  // the near planes and the per-patch rotation noise of F (see fundamental_mixtures.h) remain.
  EXPECT_LT(median(target_px), 1.6);
  EXPECT_LT(median(target_px), median(gyro_px))
      << "the target must see the OIS motion the gyro misses";
  EXPECT_LT(target_distance_px, gyro_distance_px);
}

TEST(FundamentalMixturesOffline, RejectedPairsKeepTheirRecordAndReason) {
  const std::string good = writeBag(5, 0.2, "fm_reject");
  FundamentalMixturesOfflineOptions options = optionsFor({good}, "fm_rejected");
  options.solver.min_inliers = 100000;  // more than any pair can have
  FundamentalMixturesSummary summary = FundamentalMixturesOffline(options).run();
  ASSERT_GT(summary.pairs_done, 0u);
  EXPECT_EQ(summary.rejected, summary.pairs_done) << summary.text();
  for (const TrainingPair& record : readRecords(options)) {
    EXPECT_FALSE(record.accepted);
    EXPECT_EQ(record.model, "none");
    EXPECT_TRUE(record.target_homographies.empty());
    EXPECT_EQ(record.gyro_homographies.size(), 9 * record.patch_count);
    EXPECT_FALSE(record.rejection_reason.empty());
    EXPECT_GT(record.match_count, 0u);
  }

  // IMU time far past the recording: no gyro input, the record says so.
  options = optionsFor({good}, "fm_no_gyro");
  options.gyro.rolling_shutter.time_offset_s = 100.0;
  summary = FundamentalMixturesOffline(options).run();
  EXPECT_EQ(summary.rejected, summary.pairs_done) << summary.text();
  ASSERT_EQ(summary.rejections.size(), 1u) << summary.text();
  EXPECT_EQ(summary.rejections.begin()->first.rfind("gyro: ", 0), 0u) << summary.text();
  for (const TrainingPair& record : readRecords(options)) {
    EXPECT_TRUE(record.gyro_homographies.empty());
    EXPECT_EQ(record.rejection_reason.rfind("gyro: ", 0), 0u) << record.rejection_reason;
  }
}

TEST(FundamentalMixturesOffline, StopFlagLeavesAReadableOutput) {
  const std::string good = writeBag(3, 0.2, "fm_stop");
  const FundamentalMixturesOfflineOptions options = optionsFor({good}, "fm_stopped");
  const std::atomic<bool> stop{true};
  const FundamentalMixturesSummary summary = FundamentalMixturesOffline(options).run(&stop);
  EXPECT_TRUE(summary.interrupted);
  EXPECT_EQ(summary.pairs_done, 0u);
  EXPECT_TRUE(readRecords(options).empty());  // opens: the bag was closed with its index
}

TEST(FundamentalMixturesOffline, InvalidOptionsAreRejectedByName) {
  FundamentalMixturesOfflineOptions options = optionsFor({}, "fm_none");
  EXPECT_THROW(FundamentalMixturesOffline{options}, std::invalid_argument);
  options.bags = {options.output_path};
  try {
    FundamentalMixturesOffline job(options);
    FAIL() << "the output may not overwrite an input";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("output"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deep_ois
