// The command-line tools on a real phone's lens log (the Pixel 4 DVS logs of ../shared/data,
// skipped when absent), as a user runs them after convert_recording (issue 31 #5, #6):
//  - train_stabiliser --target log names lens_shift_time_offset (sign and value) where the log's
//    clock does not fit the gyro, not calibrate (which needs images the log has none of), and
//    --fit-time-offset moves the log as lens_log_fit does, with a better held-out residual;
//  - predict_lens on the converted bag uses the lens log it has without being told (and the
//    simulator's truth on a simulated bag, always run).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "run_command.h"
#include "shared_data.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

// The held-out "with the model" cell of train_stabiliser's lens-motion table, pixels.
double heldOutRmsPx(const std::string& report) {
  std::smatch match;
  const std::regex row(R"(\| held out \(1 recording\) \| \d+ \| [0-9.]+ \| ([0-9.]+) \|)");
  if (!std::regex_search(report, match, row)) return -1.0;
  return std::stod(match[1].str());
}

class Pixel4LensLog : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string logs = sharedData("pixel4_dvs_ois");
    if (!fs::exists(logs + "/calib.txt")) GTEST_SKIP() << "phone recording not found: " << logs;
    dir_ = ::testing::TempDir() + "/deep_ois_lens_log_tools_" +
           std::to_string(::testing::UnitTest::GetInstance()->random_seed());
    fs::create_directories(dir_);
    std::string output;
    for (const std::string& part : {std::string("train --to 6"), std::string("test --from 6")}) {
      const std::string name = part.substr(0, part.find(' '));
      const std::string span = part.substr(part.find(' ') + 1);
      ASSERT_EQ(test::runCommand(std::string(DEEP_OIS_CONVERT_RECORDING_EXE) + " --quiet --recording " + logs +
                                     " --out " + dir_ + "/p4_" + name + ".bag --drop-uncovered-frames " + span +
                                     " 2>&1",
                                 output),
                0)
          << output;
    }
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  std::string train(const std::string& flags, int* status) {
    std::string output;
    *status = test::runCommand(std::string(DEEP_OIS_TRAIN_STABILISER_EXE) + " --no-progress --target log --bags " +
                                   dir_ + "/p4_train.bag --held-out " + dir_ + "/p4_test.bag --gyro-config " + dir_ +
                                   "/p4_train.gyro_flow.yaml --out " + dir_ + "/model.yaml " + flags + " 2>&1",
                               output);
    return output;
  }

  std::string dir_;
};

TEST_F(Pixel4LensLog, TrainStabiliserNamesAndFitsTheLensLogsClock) {
  int status = 0;
  const std::string as_logged = train("", &status);
  EXPECT_EQ(status, 3) << as_logged;  // the log's clock does not fit the gyro
  // What to set, its sign convention and the flag; not calibrate, which needs images.
  EXPECT_NE(as_logged.find("lens_shift_time_offset: the lens motion fits best"), std::string::npos) << as_logged;
  EXPECT_NE(as_logged.find("ahead of the gyro"), std::string::npos) << as_logged;
  EXPECT_NE(as_logged.find("s to lens_shift_time_offset in the gyro config (camera time = logged stamp + "
                           "lens_shift_time_offset)"),
            std::string::npos)
      << as_logged;
  EXPECT_NE(as_logged.find("--fit-time-offset"), std::string::npos) << as_logged;
  EXPECT_EQ(as_logged.find("run calibrate"), std::string::npos) << as_logged;

  const std::string timed = train("--fit-time-offset", &status);
  EXPECT_EQ(status, 0) << timed;
  // The Pixel 4's log leads its gyro by about 2.6 ms: moved later, a positive offset.
  std::smatch moved;
  ASSERT_TRUE(std::regex_search(timed, moved, std::regex(R"(The lens log was moved by \+([0-9.]+) ms)"))) << timed;
  EXPECT_NEAR(std::stod(moved[1].str()), 2.6, 1.0) << timed;
  EXPECT_NE(timed.find("Set lens_shift_time_offset: 0.00"), std::string::npos) << timed;
  const double before = heldOutRmsPx(as_logged), after = heldOutRmsPx(timed);
  ASSERT_GT(before, 0.0) << as_logged;
  ASSERT_GT(after, 0.0) << timed;
  EXPECT_LT(after, before) << "held-out RMS " << before << " px as logged, " << after << " px moved";

  // predict_lens on the converted real recording: the bag's lens log, without --target.
  std::string predicted;
  EXPECT_EQ(test::runCommand(std::string(DEEP_OIS_PREDICT_LENS_EXE) + " --bag " + dir_ + "/p4_test.bag --model " +
                                 dir_ + "/model.yaml --gyro-config " + dir_ + "/p4_train.gyro_flow.yaml --out " +
                                 dir_ + "/predicted 2>&1",
                             predicted),
            0)
      << predicted;
  EXPECT_NE(predicted.find("comparing with the bag's lens-shift log (--target log)"), std::string::npos) << predicted;
  EXPECT_TRUE(fs::exists(dir_ + "/predicted_motion.csv")) << predicted;
}

// A simulated recording (the committed sample bag) has the simulator's truth: predict_lens takes
// it without being told.
TEST(PredictLens, TakesTheSimulatorTruthOfASimulatedBag) {
  const std::string prefix = ::testing::TempDir() + "/deep_ois_predict_lens_sample";
  std::string output;
  EXPECT_EQ(test::runCommand(std::string(DEEP_OIS_PREDICT_LENS_EXE) + " --bag " DEEP_OIS_SOURCE_DIR
                                 "/bags/sample.bag --model " DEEP_OIS_SOURCE_DIR
                                 "/models/stabiliser_generic.yaml --gyro-config " DEEP_OIS_SOURCE_DIR
                                 "/config/gyro_flow.yaml --out " +
                                 prefix + " 2>&1",
                             output),
            0)
      << output;
  EXPECT_NE(output.find("comparing with the bag's simulator truth (--target truth)"), std::string::npos) << output;
  for (const char* suffix : {"_position.csv", "_motion.csv", "_motion.png"}) fs::remove(prefix + suffix);
}

}  // namespace
}  // namespace deep_ois
