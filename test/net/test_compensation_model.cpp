// The compensation network through its torch-free interface: shapes on odd sizes, save/load,
// metadata checks on load, and a short training run that must lower the loss.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <algorithm>
#include <random>
#include <string>

#include <Eigen/Geometry>

#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/flow/motion_history.h"
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#include "deep_ois/net/flow_trainer.h"

namespace deep_ois {
namespace {

// One torch thread: OpenMP worker threads spin-wait, which turns a 2-core machine running other
// jobs (CI) into a crawl.
class OneTorchThread : public ::testing::Environment {
 public:
  void SetUp() override { setTorchThreads(1); }
};
::testing::Environment* const kOneTorchThread = ::testing::AddGlobalTestEnvironment(new OneTorchThread);

std::string tempPath(const std::string& name) {
  return "/tmp/deep_ois_test_net_" + std::to_string(::getpid()) + "_" + name;
}

// A small network so that the tests run in seconds: 3 levels, odd working grid, the gyro flow
// alone as input.
ModelMetadata tinyMetadata() {
  ModelMetadata m = presetMetadata("fast");
  m.preset = "custom";
  m.architecture.widths = {8, 16, 16};
  m.working_grid = cv::Size(45, 33);
  m.setHistoryTimeConstants({});
  return m;
}

// The same with a motion history of two leaky sums.
ModelMetadata tinyHistoryMetadata() {
  ModelMetadata m = tinyMetadata();
  m.setHistoryTimeConstants({0.05, 0.2});
  return m;
}

constexpr std::int64_t kFrameNs = 33333333;  // 30 fps

cv::Mat randomFlow(cv::Size size, unsigned seed) {
  cv::Mat flow(size, CV_32FC2);
  cv::RNG rng(seed);
  rng.fill(flow, cv::RNG::UNIFORM, -3.0, 3.0);
  return flow;
}

bool identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(CompensationModel, PresetsValidate) {
  EXPECT_EQ(presetMetadata("fast").validate(), "");
  const ModelMetadata paper = presetMetadata("paper");
  EXPECT_EQ(paper.validate(), "");
  EXPECT_EQ(paper.architecture.widths, (std::vector<int>{32, 64, 128, 256, 256}));
  EXPECT_EQ(paper.working_grid, cv::Size(360, 270));
  EXPECT_THROW(presetMetadata("huge"), std::runtime_error);
}

TEST(CompensationModel, KeepsTheSizeOfAnyFlowIncludingOddOnes) {
  for (const cv::Size working : {cv::Size(45, 33), cv::Size(31, 17), cv::Size(64, 48)}) {
    ModelMetadata m = tinyMetadata();
    m.working_grid = working;
    const CompensationModel model(m);
    for (const cv::Size size : {cv::Size(45, 33), cv::Size(37, 29), cv::Size(360, 270), cv::Size(91, 67)}) {
      const cv::Mat out = model.compensate(randomFlow(size, 3));
      ASSERT_EQ(out.size(), size) << "working grid " << working;
      ASSERT_EQ(out.type(), CV_32FC2);
      EXPECT_TRUE(cv::checkRange(out)) << "non-finite output";
    }
  }
}

TEST(CompensationModel, AnUntrainedResidualModelPassesTheGyroFlowThrough) {
  const CompensationModel model(tinyMetadata(), 4);
  const cv::Mat flow = randomFlow(cv::Size(45, 33), 8);  // on the working grid: no resampling
  EXPECT_LT(cv::norm(model.compensate(flow), flow, cv::NORM_INF), 1e-5);
}

TEST(CompensationModel, IsFullyConvolutionalOnItsWorkingGrid) {
  // A translated input pattern gives a translated output away from the borders: the network
  // has no position-dependent layer.
  ModelMetadata m = tinyMetadata();
  m.architecture.residual = false;
  m.working_grid = cv::Size(160, 128);
  const CompensationModel model(m, 5);
  cv::Mat flow(128, 160, CV_32FC2, cv::Scalar(0, 0));
  cv::Mat shifted = flow.clone();
  const cv::Mat bump = randomFlow(cv::Size(8, 8), 9);
  bump.copyTo(flow(cv::Rect(68, 56, 8, 8)));
  bump.copyTo(shifted(cv::Rect(76, 64, 8, 8)));  // 8 px: a multiple of the 2 pooling steps (4)
  const cv::Mat out = model.compensate(flow), out_shifted = model.compensate(shifted);
  // Compared more than the receptive radius (~30 px) away from the borders.
  const double difference = cv::norm(out(cv::Rect(48, 40, 48, 40)), out_shifted(cv::Rect(56, 48, 48, 40)), cv::NORM_INF);
  EXPECT_LT(difference, 1e-4);
}

TEST(CompensationModel, SaveAndLoadGiveIdenticalOutputs) {
  ModelMetadata m = tinyMetadata();
  m.input_mean_px = {0.25, -0.5};
  m.input_std_px = {2.0, 3.0};
  m.training.data_files = {"a.bag"};
  m.training.train_loss = {1.0, 0.5};
  const CompensationModel model(m, 11);
  const std::string path = tempPath("roundtrip.pt");
  model.save(path);
  const CompensationModel loaded = CompensationModel::load(path);
  std::remove(path.c_str());
  EXPECT_EQ(loaded.metadata().toYaml(), model.metadata().toYaml());
  const cv::Mat input = randomFlow(cv::Size(90, 68), 2);
  EXPECT_TRUE(identical(model.compensate(input), loaded.compensate(input)));
}

TEST(CompensationModel, LoadNamesTheFileAndTheProblem) {
  auto expectError = [](const std::string& path, const std::string& fragment) {
    try {
      CompensationModel::load(path);
      ADD_FAILURE() << "loading " << path << " did not fail";
    } catch (const ModelFileError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find(fragment), std::string::npos) << what;
    }
  };
  expectError(tempPath("missing.pt"), "does not exist");

  const std::string garbage = tempPath("garbage.pt");
  std::ofstream(garbage) << "this is not a model";
  expectError(garbage, "not a torch archive");
  std::remove(garbage.c_str());

  // A truncated file (a download cut short).
  const std::string good = tempPath("good.pt"), truncated = tempPath("truncated.pt");
  CompensationModel(tinyMetadata()).save(good);
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  expectError(truncated, "model file");
  std::remove(good.c_str());
  std::remove(truncated.c_str());

  // Weights of one architecture under metadata that claims another.
  const std::string mismatched = tempPath("mismatched.pt");
  CompensationModel model(tinyMetadata());
  model.metadata().architecture.widths = {8, 16, 32};
  model.save(mismatched);
  expectError(mismatched, "shape");
  std::remove(mismatched.c_str());
}

TEST(CompensationStream, FeedsTheModelTheMotionHistoryOfTheEarlierPairs) {
  ModelMetadata m = tinyHistoryMetadata();
  m.architecture.residual = false;  // an untrained residual model would ignore its history
  const CompensationModel model(m, 21);
  // Without the history it needs, the model refuses rather than guess.
  EXPECT_THROW(model.compensate(randomFlow(m.working_grid, 1)), std::invalid_argument);

  CompensationStream stream(model);
  MotionHistory reference(m.history_time_constants_s, m.working_grid);
  cv::Mat first_output;
  for (int n = 0; n < 4; ++n) {
    const cv::Mat flow = randomFlow(m.working_grid, 30 + n);
    const std::int64_t a = n * kFrameNs, b = a + kFrameNs;
    const cv::Mat expected = model.compensate(flow, reference.before(a));
    reference.add(a, b, flow);
    const cv::Mat out = stream.compensate(flow, a, b);
    EXPECT_TRUE(identical(out, expected)) << "pair " << n;
    if (n == 0) first_output = out;
  }
  EXPECT_EQ(stream.history().pairsSinceReset(), 4u);
  // The same flow after motion gives another answer than at the start: the history matters.
  const cv::Mat again = stream.compensate(randomFlow(m.working_grid, 30), 4 * kFrameNs, 5 * kFrameNs);
  EXPECT_GT(cv::norm(again, first_output, cv::NORM_INF), 1e-4);
  // A dropped frame restarts the history: the pair is treated as the first of a stream.
  const cv::Mat after_gap = stream.compensate(randomFlow(m.working_grid, 30), 9 * kFrameNs, 10 * kFrameNs);
  EXPECT_TRUE(identical(after_gap, first_output));
  EXPECT_THROW(stream.compensate(randomFlow(m.working_grid, 1), kFrameNs, kFrameNs), std::invalid_argument);
}

TEST(ModelMetadata, YamlRoundTripAndFieldNamingErrors) {
  ModelMetadata m = tinyMetadata();
  m.training.validation_epe_px = {0.5, 0.25};
  m.training.data_sha256 = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
  const ModelMetadata back = ModelMetadata::fromYaml(m.toYaml());
  EXPECT_EQ(back.toYaml(), m.toYaml());
  EXPECT_EQ(back.training.data_sha256, m.training.data_sha256);
  EXPECT_EQ(m.toYaml().find("data_hash"), std::string::npos) << m.toYaml();

  // A model from before the SHA-256 (as models/fast.pt was until 2026-11): its FNV-1a hash under
  // data_hash is read as what it is, not as a SHA-256, and written back unchanged.
  std::string fnv_yaml = m.toYaml();
  const std::size_t sha_at = fnv_yaml.find("data_sha256: ");
  ASSERT_NE(sha_at, std::string::npos) << fnv_yaml;
  fnv_yaml.replace(sha_at, fnv_yaml.find('\n', sha_at) - sha_at, "data_hash: 25df48db6eac2a9b");
  const ModelMetadata old_model = ModelMetadata::fromYaml(fnv_yaml);
  EXPECT_EQ(old_model.training.data_sha256, "");
  EXPECT_EQ(old_model.training.legacy_data_fnv1a64, "25df48db6eac2a9b");
  EXPECT_EQ(ModelMetadata::fromYaml(old_model.toYaml()).training.legacy_data_fnv1a64,
            "25df48db6eac2a9b");

  std::string yaml = m.toYaml();
  const std::string without_grid = yaml.substr(0, yaml.find("working_grid")) + yaml.substr(yaml.find("input_mean_px"));
  try {
    ModelMetadata::fromYaml(without_grid);
    ADD_FAILURE() << "missing working_grid accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("working_grid"), std::string::npos) << e.what();
  }
  ModelMetadata bad = m;
  bad.input_std_px = {0.0, 1.0};
  EXPECT_NE(bad.validate().find("input_std_px"), std::string::npos);
  bad = m;
  bad.format_version = 99;
  EXPECT_THROW(ModelMetadata::fromYaml(bad.toYaml()), std::runtime_error);

  // The motion history: kept through YAML, its statistics must match its time constants, and a
  // model file from before it (no history fields) reads as a gyro-flow-only model.
  const ModelMetadata with_history = tinyHistoryMetadata();
  EXPECT_EQ(ModelMetadata::fromYaml(with_history.toYaml()).history_time_constants_s,
            with_history.history_time_constants_s);
  EXPECT_EQ(with_history.inputChannels(), 6);
  bad = with_history;
  bad.history_std_px.pop_back();
  EXPECT_NE(bad.validate().find("history_std_px"), std::string::npos);
  bad = with_history;
  bad.history_time_constants_s[0] = -1.0;
  EXPECT_NE(bad.validate().find("history_time_constants_s"), std::string::npos);
  std::string old_yaml = m.toYaml();
  for (const std::string key : {"history_time_constants_s", "history_mean_px", "history_std_px"}) {
    const std::size_t at = old_yaml.find(key);
    ASSERT_NE(at, std::string::npos) << key;
    old_yaml.erase(at, old_yaml.find('\n', at) + 1 - at);
  }
  EXPECT_EQ(ModelMetadata::fromYaml(old_yaml).inputChannels(), 2);

  // The camera it was trained for: kept through YAML (a readout that was not recorded stays
  // unknown); a model from before it reads as an unknown camera; a malformed field is named.
  ModelMetadata with_camera = m;
  with_camera.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, CameraDescription::kUnknownReadout, 30.0};
  const std::string camera_yaml = with_camera.toYaml();
  EXPECT_EQ(camera_yaml.find("readout_time_s"), std::string::npos) << camera_yaml;
  const ModelMetadata camera_back = ModelMetadata::fromYaml(camera_yaml);
  EXPECT_EQ(camera_back.camera.summary(), with_camera.camera.summary());
  EXPECT_FALSE(camera_back.camera.readoutKnown());
  std::string no_camera = camera_yaml;
  no_camera.erase(no_camera.find("camera:"), no_camera.find("training:") - no_camera.find("camera:"));
  EXPECT_FALSE(ModelMetadata::fromYaml(no_camera).camera.known());
  std::string bad_camera = camera_yaml;
  bad_camera.replace(bad_camera.find("fx: 500"), 7, "fx: wide");
  try {
    ModelMetadata::fromYaml(bad_camera);
    ADD_FAILURE() << "a malformed camera.fx was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera.fx"), std::string::npos) << e.what();
  }
}

// The synthetic sets' camera: 360x270, focal length 250 px.
CameraModel syntheticCamera() {
  Eigen::Matrix3d K;
  K << 250, 0, 179.5, 0, 250, 134.5, 0, 0, 1;
  return CameraModel(360, 270, K);
}

// Synthetic OIS: the target is the gyro homography followed by an image shift that depends on
// the rotation (a lens that moves against the shake), which the network has to learn.
std::vector<TrainingSample> syntheticSet(int count, unsigned seed) {
  const CameraModel camera = syntheticCamera();
  const Eigen::Matrix3d K = camera.K();
  std::mt19937 rng = streamGenerator(seed, 1);
  std::vector<TrainingSample> set;
  for (int n = 0; n < count; ++n) {
    TrainingSample sample;
    sample.camera = camera;
    sample.source = "synthetic_" + std::to_string(n % 4);
    const Eigen::Vector3d axis_rate(0.02 * gaussian(rng), 0.02 * gaussian(rng), 0.005 * gaussian(rng));
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d angle = axis_rate * (1.0 + 0.05 * i);
      const Eigen::Matrix3d R = Eigen::AngleAxisd(angle.norm(), angle.norm() > 0 ? angle.normalized() : Eigen::Vector3d::UnitZ())
                                    .toRotationMatrix();
      const Eigen::Matrix3d H = K * R * K.inverse();
      Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
      shift(0, 2) = -0.6 * 250 * angle.y();
      shift(1, 2) = 0.6 * 250 * angle.x();
      sample.gyro_homographies.push_back(H / H(2, 2));
      const Eigen::Matrix3d target = shift * H;
      sample.target_homographies.push_back(target / target(2, 2));
    }
    set.push_back(sample);
  }
  return set;
}

TEST(FlowTrainer, AShortRunLowersTheLossAndResumesFromItsCheckpoint) {
  const std::vector<TrainingSample> train = syntheticSet(48, 1), validation = syntheticSet(16, 2);
  TrainerOptions options;
  options.epochs = 6;
  options.learning_rate = 2e-3;
  options.checkpoint_path = tempPath("checkpoint.pt");
  CompensationModel model(tinyMetadata(), 3);
  const TrainingOutcome outcome = trainCompensationModel(model, train, validation, options, {}, {});
  EXPECT_EQ(outcome.epochs_done, 6);
  const TrainingRecord& record = model.metadata().training;
  ASSERT_EQ(record.train_loss.size(), 6u);
  ASSERT_EQ(record.validation_epe_px.size(), 6u);
  EXPECT_LT(record.train_loss.back(), 0.7 * record.train_loss.front());
  EXPECT_LT(record.validation_epe_px.back(), record.validation_epe_px.front());
  // It learned the shift: better than passing the gyro flow through.
  EXPECT_LT(record.validation_epe_px.back(), record.validation_gyro_epe_px.back());
  EXPECT_NE(model.metadata().input_std_px[0], 1.0) << "normalisation statistics not computed";

  // Resuming the 6-epoch checkpoint for 2 more epochs keeps the history and goes on.
  options.resume = true;
  options.epochs = 8;
  CompensationModel resumed(tinyMetadata(), 99);
  const TrainingOutcome second = trainCompensationModel(resumed, train, validation, options, {}, {});
  EXPECT_TRUE(second.resumed);
  EXPECT_EQ(second.resumed_from_epoch, 6);
  const TrainingRecord& continued = resumed.metadata().training;
  ASSERT_EQ(continued.train_loss.size(), 8u);
  for (int e = 0; e < 6; ++e) EXPECT_EQ(continued.train_loss[e], record.train_loss[e]);
  EXPECT_EQ(resumed.metadata().input_mean_px, model.metadata().input_mean_px);
  std::remove(options.checkpoint_path.c_str());
}

// Synthetic OIS with memory: recordings of consecutive pairs whose image shift depends on the
// motion *before* the pair (a lens centred by a high-pass: its position is a leaky sum of the
// earlier rotations), independent of the pair's own rotation. Only a model with the motion
// history can learn it.
std::vector<TrainingSample> syntheticSequences(int recordings, int pairs_per_recording, unsigned seed) {
  const CameraModel camera = syntheticCamera();
  const Eigen::Matrix3d K = camera.K();
  std::mt19937 rng = streamGenerator(seed, 2);
  std::vector<TrainingSample> set;
  for (int r = 0; r < recordings; ++r) {
    Eigen::Vector2d lens_px = Eigen::Vector2d::Zero();  // leaky sum of the earlier rotations, pixels
    for (int n = 0; n < pairs_per_recording; ++n) {
      const Eigen::Vector3d angle(0.01 * gaussian(rng), 0.01 * gaussian(rng), 0.0);
      const Eigen::Matrix3d H = K * Eigen::AngleAxisd(angle.norm(), angle.normalized()).toRotationMatrix() * K.inverse();
      Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
      shift(0, 2) = lens_px.x();
      shift(1, 2) = lens_px.y();
      TrainingSample sample;
      sample.camera = camera;
      sample.source = "sequence_" + std::to_string(seed) + "_" + std::to_string(r);
      sample.stamp_a_ns = n * kFrameNs;
      sample.stamp_b_ns = (n + 1) * kFrameNs;
      const Eigen::Matrix3d target = shift * H;
      sample.gyro_homographies.assign(6, H / H(2, 2));
      sample.target_homographies.assign(6, target / target(2, 2));
      set.push_back(sample);
      lens_px = std::exp(-1.0 / 6.0) * lens_px - 0.5 * 250.0 * Eigen::Vector2d(-angle.y(), angle.x());
    }
  }
  // Shuffled and one pair without a target: the trainer must order by recording and stamp and
  // carry the history across the pair the job rejected.
  std::shuffle(set.begin(), set.end(), rng);
  set[3].target_homographies.clear();
  return set;
}

TEST(FlowTrainer, LearnsAnOisThatDependsOnTheMotionHistory) {
  const std::vector<TrainingSample> train = syntheticSequences(8, 16, 1), validation = syntheticSequences(3, 16, 2);
  TrainerOptions options;
  options.epochs = 8;
  options.learning_rate = 3e-3;
  double epe[2], gyro_epe = 0.0;
  for (int with_history = 0; with_history < 2; ++with_history) {
    CompensationModel model(with_history ? tinyHistoryMetadata() : tinyMetadata(), 3);
    trainCompensationModel(model, train, validation, options, {}, {});
    epe[with_history] = model.metadata().training.validation_epe_px.back();
    gyro_epe = model.metadata().training.validation_gyro_epe_px.back();
    EXPECT_EQ(model.metadata().training.train_pairs, train.size() - 1) << "the pair without a target is not trained on";
  }
  EXPECT_LT(epe[1], 0.6 * epe[0]) << "with history " << epe[1] << " px, without " << epe[0] << " px, gyro " << gyro_epe;
  EXPECT_LT(epe[1], 0.6 * gyro_epe);
}

TEST(FlowTrainer, RejectsEmptyOrInconsistentData) {
  CompensationModel model(tinyMetadata());
  TrainerOptions options;
  EXPECT_THROW(trainCompensationModel(model, {}, {}, options, {}, {}), std::invalid_argument);
  std::vector<TrainingSample> bad = syntheticSet(2, 4);
  bad[1].target_homographies.pop_back();
  EXPECT_THROW(trainCompensationModel(model, bad, {}, options, {}, {}), std::invalid_argument);
  options.loss = "l3";
  EXPECT_THROW(trainCompensationModel(model, syntheticSet(2, 4), {}, options, {}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
