// train_stabiliser's support: its report's wording (issue 23 #5, #15) and its ground-truth cache,
// which must answer only for the same bag content and gyro config (issue 23 #6).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "deep_ois/tools/support/stabiliser_training_cache.h"
#include "deep_ois/tools/support/stabiliser_training_report.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

StabiliserRecordingData someData() {
  StabiliserRecordingData data;
  data.frame_pairs = 1;
  data.recording.focal_px = 300.0;
  data.recording.rates = {{0.0, Eigen::Vector3d(0.1, 0.2, 0.3)},
                          {0.01, Eigen::Vector3d(0.2, 0.1, 0.0)}};
  LensMotionObservation o;
  o.t_a_s = 0.002;
  o.t_b_s = 0.008;
  o.motion_px = Eigen::Vector2d(0.5, -0.25);
  o.readout_fraction = 0.25;
  data.recording.observations = {o};
  data.camera.width = 360;
  data.camera.height = 270;
  data.camera.fx = data.camera.fy = 300.0;
  data.recorded_readout_time_s = 0.012;
  return data;
}

TEST(StabiliserTrainingReport, TrackResidualOnlyWhereThereAreTracks) {
  StabiliserRecordingData data = someData();
  data.median_track_residual_px = 0.0;
  const std::string log = recordingSummary("a.bag", data, LensMotionTarget::kLensLog, false);
  EXPECT_EQ(log, "a.bag: 1 pair, 1 lens motion");
  EXPECT_EQ(recordingSummary("a.bag", data, LensMotionTarget::kSimulatorTruth, true),
            "a.bag: 1 pair, 1 lens motion (cached)");
  data.median_track_residual_px = 0.123;
  data.frame_pairs = 40;
  data.pairs_without_tracks = 2;
  EXPECT_EQ(recordingSummary("a.bag", data, LensMotionTarget::kImages, false),
            "a.bag: 40 pairs, 1 lens motion, 2 pairs with too few tracks (left out), track "
            "residual 0.123 px");
}

TEST(StabiliserTrainingReport, TablesSayCountsRatesAndBoundsPlainly) {
  const std::string table =
      lensMotionTable({{"training", 3, 900, 2.0, 0.5, 0.4}, {"held out", 1, 300, 2.1, 0.55, 0.45}});
  EXPECT_NE(table.find("| training (3 recordings) | 900 | 2.000 | 0.500 | 0.400 |"),
            std::string::npos)
      << table;
  // One recording, and the physical model's cell filled on the held-out row too.
  EXPECT_NE(table.find("| held out (1 recording) | 300 | 2.100 | 0.550 | 0.450 |"),
            std::string::npos)
      << table;

  StabiliserParameters p;
  p.pan_detection_rate_rad_s = 0.6;
  p.pan_release_corner_hz = 5.0;
  p.sensor_lag_s = 0.0;
  StabiliserFitReview review;
  review.on_bound_parameters = {"sensor_lag_s"};
  const std::string parameters = stabiliserParameterTable(p, review);
  EXPECT_NE(parameters.find("| pan detection | 0.60 rad/s, release 5.00 Hz |"), std::string::npos)
      << parameters;
  EXPECT_NE(parameters.find("| sensor lag | 0.00 ms (on the fit's bound) |"), std::string::npos)
      << parameters;
}

// The simulator's truth states the camera's readout: a gyro config that differs is named.
TEST(StabiliserTrainingReport, ARecordedReadoutOtherThanTheConfigsIsNamed) {
  StabiliserRecordingData data = someData();  // records 12 ms
  EXPECT_EQ(readoutMismatch(data, 0.012), "");
  const std::string mismatch = readoutMismatch(data, 0.022);
  EXPECT_EQ(mismatch.rfind("readout_time: the gyro config says 22.0 ms but the recording says "
                           "12.0 ms",
                           0),
            0u)
      << mismatch;
  EXPECT_NE(mismatch.find("set readout_time: 0.012"), std::string::npos) << mismatch;
  data.recorded_readout_time_s = StabiliserRecordingData::kNotRecorded;
  EXPECT_EQ(readoutMismatch(data, 0.022), "");
}

class StabiliserTrainingCache : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("deep_ois_test_cache_" +
            std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    fs::create_directories(dir_);
    bag_ = (dir_ / "recording.bag").string();
    writeBag("first content");
  }
  void TearDown() override { fs::remove_all(dir_); }
  void writeBag(const std::string& content) { std::ofstream(bag_) << content; }

  fs::path dir_;
  std::string bag_;
};

TEST_F(StabiliserTrainingCache, AnswersOnlyForTheSameContentAndGyroConfig) {
  GyroFlowParameters gyro;
  gyro.rolling_shutter.readout_time_s = 0.022;
  const std::string path = stabiliserCachePath(dir_.string(), bag_, "images");
  const StabiliserCacheKey key = stabiliserCacheKey(bag_, gyro, "images");
  writeStabiliserCache(path, key, bag_, someData());

  std::string why;
  const auto same = readStabiliserCache(path, key, bag_, &why);
  ASSERT_TRUE(same.has_value()) << why;
  ASSERT_EQ(same->recording.observations.size(), 1u);
  EXPECT_EQ(same->recording.observations[0].motion_px, Eigen::Vector2d(0.5, -0.25));
  EXPECT_EQ(same->recording.observations[0].readout_fraction, 0.25);
  EXPECT_EQ(same->recorded_readout_time_s, 0.012);
  EXPECT_EQ(same->recording.rates.size(), 2u);

  // A corrected readout in the gyro config: the cache must not answer with the old data.
  GyroFlowParameters corrected = gyro;
  corrected.rolling_shutter.readout_time_s = 0.012;
  EXPECT_FALSE(
      readStabiliserCache(path, stabiliserCacheKey(bag_, corrected, "images"), bag_, &why));
  EXPECT_EQ(why, "readout_time changed (0.022 -> 0.012)");
  GyroFlowParameters offset = gyro;
  offset.rolling_shutter.time_offset_s = -0.004;
  EXPECT_FALSE(readStabiliserCache(path, stabiliserCacheKey(bag_, offset, "images"), bag_, &why));
  EXPECT_NE(why.find("time_offset changed"), std::string::npos) << why;
  GyroFlowParameters scale = gyro;
  scale.lens_shift_convention.scale = 0.48;
  EXPECT_FALSE(readStabiliserCache(path, stabiliserCacheKey(bag_, scale, "images"), bag_, &why));
  EXPECT_NE(why.find("lens_shift_scale changed"), std::string::npos) << why;

  // Same name and size, other content (a re-recorded or re-converted bag).
  writeBag("other content");
  EXPECT_FALSE(readStabiliserCache(path, stabiliserCacheKey(bag_, gyro, "images"), bag_, &why));
  EXPECT_EQ(why, "the bag's content changed");
}

TEST_F(StabiliserTrainingCache, AnIncompleteFileIsNotData) {
  GyroFlowParameters gyro;
  const std::string path = stabiliserCachePath(dir_.string(), bag_, "truth");
  const StabiliserCacheKey key = stabiliserCacheKey(bag_, gyro, "truth");
  writeStabiliserCache(path, key, bag_, someData());
  std::string text;
  {
    std::ifstream in(path);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::ofstream(path) << text.substr(0, text.find("end\n"));
  std::string why;
  EXPECT_FALSE(readStabiliserCache(path, key, bag_, &why));
  EXPECT_EQ(why, "incomplete");
}

}  // namespace
}  // namespace deep_ois
