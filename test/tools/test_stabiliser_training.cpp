// train_stabiliser's support: its report's wording (issue 23 #5, #15) and its ground-truth cache,
// which must answer only for the same bag content and gyro config (issue 23 #6).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <filesystem>
#include <fstream>
#include <string>

#include "deep_ois/tools/support/recording_conversion_report.h"
#include "deep_ois/tools/support/stabiliser_training_cache.h"
#include "deep_ois/tools/support/stabiliser_training_choice.h"
#include "deep_ois/tools/support/stabiliser_training_report.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/pan_detection.h"

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
      lensMotionTable({{"training", 3, 900, 2.0, 0.4}, {"held out", 1, 300, 2.1, 0.45}});
  EXPECT_NE(table.find("| training (3 recordings) | 900 | 2.000 | 0.400 |"), std::string::npos) << table;
  // One recording.
  EXPECT_NE(table.find("| held out (1 recording) | 300 | 2.100 | 0.450 |"),
            std::string::npos)
      << table;

  StabiliserModel p;
  p.get<PanDetectionValues>().pan_detection_rate_rad_s = 0.6;
  p.get<PanDetectionValues>().pan_release_corner_hz = 5.0;
  p.get<ActuatorValues>().sensor_lag_s = 0.0;
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

// A camera whose lens does not move (OIS off): a gyro that shakes, and lens motions that are the
// measurement's noise alone.
StabiliserFitRecording stillLens(unsigned seed, double duration_s) {
  StabiliserFitRecording recording;
  recording.name = "still lens " + std::to_string(seed);
  recording.focal_px = 500.0;
  std::mt19937 rng(seed);
  std::normal_distribution<double> rate(0.0, 0.6), noise(0.0, 0.1);
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  for (double t = 0.0; t < duration_s; t += 0.005) {
    w = 0.95 * w + 0.05 * Eigen::Vector3d(rate(rng), rate(rng), 0.3 * rate(rng)) * 4.0;
    recording.rates.push_back({t, w});
  }
  for (double stamp = 0.0; stamp + 1.0 / 30.0 < duration_s - 0.1; stamp += 1.0 / 30.0) {
    for (int i = 0; i < 6; ++i) {
      LensMotionObservation o;
      o.readout_fraction = (i + 0.5) / 6.0;
      o.t_a_s = stamp + 0.02 * o.readout_fraction;
      o.t_b_s = o.t_a_s + 1.0 / 30.0;
      o.motion_px = Eigen::Vector2d(noise(rng), noise(rng));
      recording.observations.push_back(o);
    }
  }
  return recording;
}

// Issue 31 #4: on a recording without lens motion the candidates' pick is refused against no lens
// motion. The report names what is written (no lens motion) and the figures that decided it, not
// the refused pick as "kept"; no cell says "nan" (there is no held-out recording).
TEST(StabiliserTrainingChoice, ARecordingWithoutLensMotionReportsNoLensMotionAsKept) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 5;
  const std::vector<StabiliserFitRecording> training = {stillLens(7, 5.0)};
  const StabiliserFitResult fit = fitStabiliser(training, options);
  const StabiliserTrainingChoice choice = chooseTrainedStabiliser(fit, training, {}, options);
  ASSERT_TRUE(choice.keptNoLensMotion()) << choice.lens_check.reason;
  EXPECT_EQ(choice.keptName(), "no lens motion");
  EXPECT_TRUE(isNoLensMotion(choice.keptParameters()));
  const std::string reason = keptModelReason(choice);
  EXPECT_EQ(reason.rfind("kept 'no lens motion'", 0), 0u) << reason;
  // Said once, and of the model written only.
  EXPECT_EQ(reason.find("kept '", 1), std::string::npos) << reason;
  EXPECT_NE(reason.find("px against"), std::string::npos) << reason;
  EXPECT_NE(reason.find("the last quarter of each training recording"), std::string::npos) << reason;
  const std::string table = candidateTable(choice);
  EXPECT_EQ(table.find("nan"), std::string::npos) << table;
  EXPECT_NE(table.find("n/a"), std::string::npos) << table;
  EXPECT_NE(table.find("held out: n/a, no --held-out recordings"), std::string::npos) << table;
  EXPECT_NE(table.find(" | kept |\n"), std::string::npos) << table;
  EXPECT_NE(table.find("| no lens motion | "), std::string::npos) << table;
  EXPECT_NE(table.find("refused against no lens motion"), std::string::npos) << table;
  // The kept model's training figure is the lens motion itself (what no lens motion leaves).
  EXPECT_DOUBLE_EQ(choice.keptTrainingRmsPx(), choice.selection.candidates[choice.candidate].training.rms_without_model_px);
}

// A fit that predicts the held-out lens motion is kept, and the table marks it.
TEST(StabiliserTrainingChoice, AFitThatBeatsNoLensMotionIsKeptAndMarked) {
  StabiliserTrainingChoice choice;
  StabiliserCandidate physical;
  physical.name = "physical";
  physical.training.rms_px = 0.2;
  physical.training.rms_without_model_px = 2.0;
  physical.training.observations = 600;
  physical.held_out = physical.training;
  physical.held_out.rms_px = 0.25;
  choice.selection.candidates = {physical};
  choice.selection.figures = "held-out lens-motion RMS 0.25 px";
  choice.selection.reason = "kept 'physical': " + choice.selection.figures;
  choice.lens_check.refused = false;
  choice.lens_check.scored_on = "the held-out recordings";
  choice.lens_check.fit_rms_px = 0.25;
  choice.lens_check.no_lens_motion_rms_px = 2.0;
  const std::string reason = keptModelReason(choice);
  EXPECT_EQ(reason.rfind("kept 'physical'", 0), 0u) << reason;
  EXPECT_NE(reason.find("0.2500 px against 2.0000 px for no lens motion"), std::string::npos) << reason;
  const std::string table = candidateTable(choice);
  EXPECT_NE(table.find("| physical | 0.2000 | 0.2500 | kept |"), std::string::npos) << table;
  EXPECT_NE(table.find("| no lens motion | 2.0000 | 2.0000 |  |"), std::string::npos) << table;
  EXPECT_EQ(table.find("n/a"), std::string::npos) << table;
}

// Issue 31 #8: convert_recording's summary labels every figure and agrees counts with nouns.
TEST(RecordingConversionReport, LabelsEveryTimeAndCountsInTheRightNumber) {
  PhoneRecordingBagStats stats;
  stats.frames = 632;
  stats.first_frame_index = 1;
  stats.last_frame_index = 632;
  stats.width_px = 640;
  stats.height_px = 480;
  stats.encoding = "mono8";
  stats.imu_messages = 2238;
  stats.dropped_uncovered_frames = 1;
  stats.lens_shift_repeats_dropped = 1;
  stats.lens_shift_steps_back = 2;
  stats.first_frame_stamp = ros::Time(100, 0);
  stats.last_frame_stamp = ros::Time(121, 100000000);
  const std::vector<std::string> lines = conversionSummary("vic.bag", stats, 23.4);
  std::string all;
  for (const std::string& line : lines) all += line + "\n";
  EXPECT_NE(all.find("vic.bag: 632 frames (indices 1..632, none missing) 640x480 mono8, 2238 IMU messages, "
                     "0 lens-shift samples\n"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("frame stamps: first 100.000000000 s, last 121.100000000 s (the bag's clock), 21.1 s of "
                     "recording between them\n"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("1 frame the gyro does not cover left out"), std::string::npos) << all;
  EXPECT_NE(all.find("1 repeated sample dropped"), std::string::npos) << all;
  EXPECT_NE(all.find("2 steps back"), std::string::npos) << all;
  EXPECT_NE(all.find("converted in 23.4 s (wall time: reading, pairing and writing)"), std::string::npos) << all;
  EXPECT_EQ(all.find(" 1 frames"), std::string::npos) << all;
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
