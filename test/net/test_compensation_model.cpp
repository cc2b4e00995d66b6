// The compensation network through its torch-free interface: shapes on odd sizes, save/load,
// metadata checks on load, and a short training run that must lower the loss.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>

#include <Eigen/Geometry>

#include "deep_ois/core/homography_flow.h"
#include "deep_ois/core/portable_random.h"
#include "deep_ois/net/compensation_model.h"
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

// A small network so that the tests run in seconds: 3 levels, odd working grid.
ModelMetadata tinyMetadata() {
  ModelMetadata m = presetMetadata("fast");
  m.preset = "custom";
  m.architecture.widths = {8, 16, 16};
  m.working_grid = cv::Size(45, 33);
  return m;
}

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

TEST(ModelMetadata, YamlRoundTripAndFieldNamingErrors) {
  ModelMetadata m = tinyMetadata();
  m.training.validation_epe_px = {0.5, 0.25};
  m.training.data_hash = "0123456789abcdef";
  const ModelMetadata back = ModelMetadata::fromYaml(m.toYaml());
  EXPECT_EQ(back.toYaml(), m.toYaml());

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
}

// Synthetic OIS: the target is the gyro homography followed by an image shift that depends on
// the rotation (a lens that moves against the shake), which the network has to learn.
std::vector<TrainingSample> syntheticSet(int count, unsigned seed) {
  Eigen::Matrix3d K;
  K << 250, 0, 179.5, 0, 250, 134.5, 0, 0, 1;
  const CameraModel camera(360, 270, K);
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
