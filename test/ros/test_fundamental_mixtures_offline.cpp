// The offline Fundamental Mixtures job on simulator bags, without a roscore: one record per frame
// pair, targets close to the simulator's true OIS-camera motion, a broken input (unopenable, or
// with a corrupt chunk part-way) that costs only itself, and Ctrl-C on the command-line tool.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>

#include "deep_ois/TrainingPair.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/bag_recovery.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/bag/fundamental_mixtures_offline.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"

namespace deep_ois {
namespace {

std::string sourcePath(const std::string& relative) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/" + relative;
}

std::string writeBag(
    std::uint32_t seed, double duration_s, const std::string& name,
    rosbag::compression::CompressionType compression = rosbag::compression::Uncompressed) {
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  const sim::Simulator simulator(sim::loadSimulatorConfig(sourcePath("config/simulator/RE.yaml")),
                                 seed, duration_s);
  writeSimulationBag(simulator, path, compression, SimulationBagTopics{}, nullptr);
  return path;
}

std::uint32_t littleEndian32(const std::string& bytes, std::size_t at) {
  std::uint32_t value = 0;
  for (int k = 3; k >= 0; --k) value = (value << 8) | static_cast<unsigned char>(bytes[at + k]);
  return value;
}

// A copy of `path` (a compressed rosbag 2.0) whose middle chunk no longer decompresses, with its
// index intact: rosbag opens it, and reading stops at that chunk. Record layout (rosbag format
// 2.0): "#ROSBAG V2.0\n", then records of <header length><header><data length><data>; a header
// is fields <length>"name=value", and a chunk record has "op=\x05" and the compressed messages
// as its data. 64 bytes in the middle of that data are overwritten, which bz2's block CRC
// detects. Returns the number of chunks; *corrupted gets the index of the damaged one.
int corruptMiddleChunk(const std::string& path, const std::string& out, int* corrupted) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string magic = "#ROSBAG V2.0\n";
  if (bytes.compare(0, magic.size(), magic) != 0) return 0;
  std::vector<std::pair<std::size_t, std::size_t>> chunk_data;  // offset, length
  for (std::size_t at = magic.size(); at + 8 <= bytes.size();) {
    const std::size_t header_length = littleEndian32(bytes, at);
    const std::size_t header = at + 4, data = header + header_length + 4;
    if (data > bytes.size()) break;
    const std::size_t data_length = littleEndian32(bytes, header + header_length);
    bool is_chunk = false;
    for (std::size_t field = header; field + 4 <= header + header_length;) {
      const std::size_t field_length = littleEndian32(bytes, field);
      if (bytes.compare(field + 4, field_length, std::string("op=\x05", 4)) == 0) is_chunk = true;
      field += 4 + field_length;
    }
    if (is_chunk) chunk_data.emplace_back(data, data_length);
    at = data + data_length;
  }
  if (chunk_data.size() < 3) return static_cast<int>(chunk_data.size());
  *corrupted = static_cast<int>(chunk_data.size() / 2);
  const auto [offset, length] = chunk_data[*corrupted];
  for (std::size_t k = 0; k < 64; ++k) bytes[offset + length / 2 + k] ^= 0x5a;
  std::ofstream(out, std::ios::binary) << bytes;
  return static_cast<int>(chunk_data.size());
}

// The first `fraction` of the bytes of `whole`, as a copy cut short while being written leaves it.
std::string writeTruncatedBag(const std::string& whole, double fraction, const std::string& name) {
  std::ifstream in(whole, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  std::ofstream(path, std::ios::binary) << bytes.substr(0, static_cast<std::size_t>(bytes.size() * fraction));
  return path;
}

// A file that is no bag at all: nothing in it can be recovered.
std::string writeNotABag(const std::string& name) {
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  std::ofstream(path, std::ios::binary) << "this is not a rosbag\n";
  return path;
}

FundamentalMixturesOfflineOptions optionsFor(const std::vector<std::string>& bags,
                                             const std::string& out) {
  FundamentalMixturesOfflineOptions options;
  options.bags = bags;
  options.output_path = ::testing::TempDir() + "/" + out + ".bag";
  options.gyro = loadGyroFlowParameters(YamlParameters(sourcePath("config/gyro_flow.yaml")));
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
  const std::string truncated = writeNotABag("fm_not_a_bag");
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
    const auto points_a = unflattenPoints(truth.points_a),
               points_b = unflattenPoints(truth.points_b);
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
  // Measured (seed 7, 0.5 s, RE; all 15 pairs rotation-only, see ModelSelection): target 0.53 px
  // median corner difference, gyro 1.98 px; geometry distance 0.31 px vs 1.98 px. (With the F
  // rotations, as the paper: 1.21 px and 1.55 px.) The target is not exact: the translation
  // parallax of the near planes remains.
  EXPECT_LT(median(target_px), 0.8);
  EXPECT_LT(target_distance_px / accepted, 0.5);
  EXPECT_LT(median(target_px), median(gyro_px))
      << "the target must see the OIS motion the gyro misses";
  EXPECT_LT(target_distance_px, gyro_distance_px);
}

// A bag whose index is intact but whose middle chunk is corrupt: the job reports the bag and the
// problem, keeps every pair it could read before the chunk, goes on with the next bag, and closes
// the output cleanly.
TEST(FundamentalMixturesOffline, CorruptChunkKeepsEveryPairBeforeIt) {
  const std::string intact = writeBag(9, 0.45, "fm_intact_bz2", rosbag::compression::BZ2);
  const std::string corrupt = ::testing::TempDir() + "/fm_corrupt_chunk.bag";
  int corrupted = -1;
  const int chunks = corruptMiddleChunk(intact, corrupt, &corrupted);
  ASSERT_GE(chunks, 3) << "the test bag needs chunks before and after the damaged one";

  // How far the images can be read: the job must keep every pair up to there.
  std::size_t readable_frames = 0;
  std::string reader_error;
  {
    BagFrameReader reader(corrupt, BagSequenceTopics().image);
    ASSERT_GT(reader.frameCount(), 0u);
    BagFrame frame;
    try {
      while (reader.next(frame)) ++readable_frames;
    } catch (const std::runtime_error& e) {
      reader_error = e.what();
    }
    ASSERT_FALSE(reader_error.empty()) << "the damaged chunk must not read as valid";
    ASSERT_LT(readable_frames, reader.frameCount());
  }
  ASSERT_GE(readable_frames, 3u) << "chunk " << corrupted << " of " << chunks;

  const FundamentalMixturesOfflineOptions reference = optionsFor({intact}, "fm_intact_train");
  const FundamentalMixturesSummary reference_summary = FundamentalMixturesOffline(reference).run();
  ASSERT_TRUE(reference_summary.bag_errors.empty()) << reference_summary.text();
  const std::vector<TrainingPair> full = readRecords(reference);

  const FundamentalMixturesOfflineOptions options =
      optionsFor({corrupt, intact}, "fm_corrupt_train");
  const FundamentalMixturesSummary summary = FundamentalMixturesOffline(options).run();
  std::cout << "[ measured ] chunk " << corrupted << " of " << chunks << " damaged, "
            << readable_frames << " frames readable; " << summary.text();
  ASSERT_EQ(summary.bag_errors.size(), 1u) << summary.text();
  const std::string& error = summary.bag_errors[0];
  EXPECT_EQ(error.rfind(corrupt + ": ", 0), 0u) << "the error names the bag: " << error;
  EXPECT_NE(error.find("corrupt"), std::string::npos) << "and the problem: " << error;

  // readRecords opens the output: it was closed with its index despite the failure.
  std::vector<TrainingPair> kept, next_bag;
  for (const TrainingPair& record : readRecords(options)) {
    (record.source_bag == corrupt ? kept : next_bag).push_back(record);
  }
  EXPECT_EQ(next_bag.size(), full.size()) << "the job goes on with the next bag";
  ASSERT_EQ(kept.size(), readable_frames - 1) << "every pair before the damaged chunk";
  EXPECT_EQ(summary.pairs_done, kept.size() + next_bag.size());
  std::size_t identical = 0;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(kept[k].header.stamp, full[k].header.stamp);
    EXPECT_EQ(kept[k].previous_stamp, full[k].previous_stamp);
    if (kept[k].accepted == full[k].accepted &&
        kept[k].target_homographies == full[k].target_homographies &&
        kept[k].gyro_homographies == full[k].gyro_homographies) {
      ++identical;
    } else {
      // Only a pair whose IMU samples lay in the damaged chunk may differ, and it says so.
      EXPECT_EQ(kept[k].rejection_reason.rfind("gyro: ", 0), 0u)
          << "pair " << k << ": " << kept[k].rejection_reason;
    }
  }
  // The IMU runs ahead of the frames by at most a readout: one pair (two with chunk bounds).
  EXPECT_GE(identical + 2, kept.size()) << identical << " of " << kept.size() << " identical";
}

// A recording cut at 60 % of its bytes (no index: rosbag cannot open it): the job reads its chunks
// and keeps every pair before the cut, identical to the same pairs from the whole recording, and
// says what was lost.
TEST(FundamentalMixturesOffline, BagCutAt60PercentKeepsThePairsBeforeTheCut) {
  const std::string whole = writeBag(12, 0.5, "fm_whole_lz4", rosbag::compression::LZ4);
  const std::string cut = writeTruncatedBag(whole, 0.6, "fm_cut_60");
  EXPECT_THROW(rosbag::Bag(cut, rosbag::bagmode::Read), rosbag::BagException) << "the cut bag has no index";

  const FundamentalMixturesOfflineOptions reference = optionsFor({whole}, "fm_whole_train");
  ASSERT_TRUE(FundamentalMixturesOffline(reference).run().bag_errors.empty());
  const std::vector<TrainingPair> full = readRecords(reference);
  ASSERT_GE(full.size(), 10u);

  const FundamentalMixturesOfflineOptions options = optionsFor({cut}, "fm_cut_train");
  const FundamentalMixturesSummary summary = FundamentalMixturesOffline(options).run();
  std::cout << "[ measured ] " << summary.text();
  ASSERT_EQ(summary.bag_errors.size(), 1u) << summary.text();
  EXPECT_EQ(summary.bag_errors[0].rfind(cut + ": the bag has no valid index", 0), 0u) << summary.bag_errors[0];
  EXPECT_NE(summary.bag_errors[0].find("the rest is lost"), std::string::npos) << summary.bag_errors[0];
  const std::vector<TrainingPair> kept = readRecords(options);
  // Images of 360x270 RGB are ~290 KB: the last (768 KB) chunk before the cut holds at most 3.
  EXPECT_GE(kept.size() + 4, static_cast<std::size_t>(0.6 * full.size())) << kept.size() << " of " << full.size();
  ASSERT_LT(kept.size(), full.size());
  EXPECT_EQ(summary.pairs_done, kept.size());
  std::size_t identical = 0;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(kept[k].source_bag, cut);
    EXPECT_EQ(kept[k].header.stamp, full[k].header.stamp);
    identical += kept[k].accepted == full[k].accepted && kept[k].gyro_homographies == full[k].gyro_homographies &&
                 kept[k].target_homographies == full[k].target_homographies;
  }
  // Only the last pair may miss IMU samples that lay after the cut.
  EXPECT_GE(identical + 1, kept.size()) << identical << " of " << kept.size() << " identical";
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

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Ctrl-C on the command-line tool, for real: SIGINT once the progress bar shows the first pair,
// then the tool must exit with 130, say so in its summary, and leave a readable output holding
// exactly the pairs it reports.
TEST(FundamentalMixturesOffline, CtrlCOnTheToolClosesTheOutputWithEveryPairDone) {
  const std::string sample = sourcePath("bags/sample.bag");
  const std::string out = ::testing::TempDir() + "/fm_ctrl_c.bag";
  const std::string stdout_path = ::testing::TempDir() + "/fm_ctrl_c.stdout";
  const std::string stderr_path = ::testing::TempDir() + "/fm_ctrl_c.stderr";
  // Leftovers of an earlier run would be read as this run's progress.
  for (const std::string& stale : {out, stdout_path, stderr_path}) std::remove(stale.c_str());
  // Eight passes over the sample: far more pairs than the tool does before the signal arrives.
  std::vector<std::string> args = {DEEP_OIS_FUNDAMENTAL_MIXTURES_EXE, "--bags"};
  for (int k = 0; k < 8; ++k) args.push_back(sample);
  for (const char* arg : {"--out", out.c_str(), "--gyro-config"}) args.push_back(arg);
  args.push_back(sourcePath("config/gyro_flow.yaml"));

  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    if (!std::freopen(stdout_path.c_str(), "w", stdout) ||
        !std::freopen(stderr_path.c_str(), "w", stderr)) {
      _exit(127);
    }
    execv(argv[0], argv.data());
    _exit(127);
  }
  // The first progress line is drawn after the first pair. Generous: a loaded machine is slow.
  bool started = false;
  for (int waited_ms = 0; waited_ms < 120000 && !started; waited_ms += 20) {
    started = readFile(stderr_path).find(" pairs/s") != std::string::npos;
    if (!started) usleep(20000);
  }
  kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(started) << "no progress line within 120 s: " << readFile(stderr_path);
  const std::string summary = readFile(stdout_path);
  std::cout << "[ measured ] " << summary;
  ASSERT_TRUE(WIFEXITED(status)) << "killed by the signal instead of stopping cleanly";
  EXPECT_EQ(WEXITSTATUS(status), 130) << summary << readFile(stderr_path);
  EXPECT_NE(summary.find("(interrupted)"), std::string::npos) << summary;

  std::size_t done = 0, total = 0;
  const std::size_t at = summary.find(out + ": ");
  ASSERT_NE(at, std::string::npos) << summary;
  ASSERT_EQ(std::sscanf(summary.c_str() + at + out.size() + 2, "%zu of %zu pairs", &done, &total),
            2)
      << summary;
  EXPECT_GE(done, 1u);
  EXPECT_LT(done, total);
  FundamentalMixturesOfflineOptions written;
  written.output_path = out;
  EXPECT_EQ(readRecords(written).size(), done) << "the output holds every pair done";
}

// SIGKILL on the command-line tool, for real: no handler runs and no index is written. Every pair
// the progress bar had reported before the kill must be recoverable from the output, each in a
// complete chunk of its own (what `rosbag reindex` needs too).
TEST(FundamentalMixturesOffline, SigkilledToolLeavesEveryFinishedPairRecoverable) {
  const std::string sample = sourcePath("bags/sample.bag");
  const std::string out = ::testing::TempDir() + "/fm_sigkill.bag";
  const std::string stderr_path = ::testing::TempDir() + "/fm_sigkill.stderr";
  for (const std::string& stale : {out, stderr_path}) std::remove(stale.c_str());
  std::vector<std::string> args = {DEEP_OIS_FUNDAMENTAL_MIXTURES_EXE, "--bags"};
  for (int k = 0; k < 8; ++k) args.push_back(sample);
  for (const char* arg : {"--out", out.c_str(), "--gyro-config"}) args.push_back(arg);
  args.push_back(sourcePath("config/gyro_flow.yaml"));

  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    if (!std::freopen("/dev/null", "w", stdout) || !std::freopen(stderr_path.c_str(), "w", stderr)) _exit(127);
    execv(argv[0], argv.data());
    _exit(127);
  }
  // The progress bar ("] N/480 pairs") after each pair written; kill once it shows 5 or more.
  auto reported = [&]() {
    const std::string progress = readFile(stderr_path);
    const std::size_t at = progress.rfind("] ");
    std::size_t done = 0;
    if (at != std::string::npos) std::sscanf(progress.c_str() + at + 2, "%zu/", &done);
    return done;
  };
  std::size_t done_before_kill = 0;
  for (int waited_ms = 0; waited_ms < 180000 && done_before_kill < 5; waited_ms += 20) {
    done_before_kill = reported();
    if (done_before_kill < 5) usleep(20000);
  }
  kill(pid, SIGKILL);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status));
  ASSERT_GE(done_before_kill, 5u) << "no 5 pairs within 180 s: " << readFile(stderr_path);

  EXPECT_THROW(rosbag::Bag(out, rosbag::bagmode::Read), rosbag::BagException) << "killed: no index";
  const ReadableBag recovered(out);
  ASSERT_TRUE(recovered.recovered());
  std::cout << "[ measured ] progress showed " << done_before_kill << " pairs before SIGKILL; " << recovered.note()
            << "\n";
  FundamentalMixturesOfflineOptions written;
  written.output_path = recovered.path();
  const std::vector<TrainingPair> records = readRecords(written);
  EXPECT_GE(records.size(), done_before_kill) << "every pair reported done is in the output";
  EXPECT_EQ(recovered.recovery().messages, records.size());
  EXPECT_EQ(recovered.recovery().chunks, records.size()) << "one complete chunk per pair";
  for (std::size_t k = 0; k < records.size(); ++k) EXPECT_EQ(records[k].source_bag, sample) << k;
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
