// The tools' charts: the CSV is written first and matplotlib (scripts/plot_csv.py) draws it; a
// machine without matplotlib keeps the CSV and says why there is no PNG.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "deep_ois/tools/support/csv_plot.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class CsvPlotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/csv_plot_test";
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::vector<double> t, logged, predicted;
    for (int i = 0; i <= 400; ++i) {
      t.push_back(6.0 + 0.005 * i);  // seconds, not a sample index
      logged.push_back(3.0 * std::sin(4.0 * t.back()));
      predicted.push_back(2.7 * std::sin(4.0 * t.back()));
    }
    writeCsvColumns(dir_ + "/lens.csv", {{"t_s", t}, {"logged_px", logged}, {"predicted_px", predicted}});
    plot_.title = "lens";
    plot_.x_column = "t_s";
    plot_.x_label = "time [s]";
    plot_.y_labels = {"lens shift [px]"};
    plot_.curves = {{"logged_px", "logged", PlotRole::kLogged, 1}, {"predicted_px", "predicted", PlotRole::kPredicted, 1}};
    plot_.width_px = 640;
    plot_.height_px = 360;
  }
  // The environment's PYTHONPATH (ROS sets one) comes back after a test that replaced it.
  void TearDown() override {
    if (python_path_) {
      setenv("PYTHONPATH", python_path_->c_str(), 1);
    } else {
      unsetenv("PYTHONPATH");
    }
  }

  std::optional<std::string> python_path_ =
      std::getenv("PYTHONPATH") ? std::optional<std::string>(std::getenv("PYTHONPATH")) : std::nullopt;
  std::string dir_;
  CsvPlot plot_;
};

TEST(CsvColumns, NonFiniteValuesAreEmptyCellsAndLengthsMustAgree) {
  const std::string path = ::testing::TempDir() + "/csv_columns.csv";
  writeCsvColumns(path, {{"t_s", {0.0, 0.5}}, {"y_px", {1.25, std::nan("")}}});
  EXPECT_EQ(readFile(path), "t_s,y_px\n0,1.25\n0.5,\n");
  EXPECT_THROW(writeCsvColumns(path, {{"t_s", {0.0, 0.5}}, {"y_px", {1.0}}}), std::invalid_argument);
  EXPECT_THROW(writeCsvColumns("/nonexistent_dir/x.csv", {{"t_s", {0.0}}}), std::runtime_error);
}

TEST_F(CsvPlotTest, TheCommandCarriesRolesPanelsAndLabels) {
  plot_.log_y = true;
  plot_.reference_lines = {0.0, 100.0};
  const std::vector<std::string> command = plotCommand("plot_csv.py", plot_, "a.csv", "a.png");
  const std::vector<std::string> expected = {
      "plot_csv.py", "a.csv", "a.png", "--x", "t_s",
      "--series", "logged_px", "logged", "logged", "1",
      "--series", "predicted_px", "predicted", "predicted", "1",
      "--x-label", "time [s]", "--y-label", "lens shift [px]", "--hline", "0", "--hline", "100",
      "--title", "lens", "--log-y", "--size", "640x360"};
  EXPECT_EQ(command, expected);
}

TEST_F(CsvPlotTest, ABarChartTakesItsColumnsAndRowFilter) {
  CsvPlot bars;
  bars.title = "RE";
  bars.x_label = "px";
  bars.bar_label_column = "method";
  bars.bar_value_column = "mean_px";
  bars.where = {{"category", "RE"}};
  const std::vector<std::string> command = plotCommand("plot_csv.py", bars, "e.csv", "e.png");
  const std::vector<std::string> expected = {"plot_csv.py", "e.csv", "e.png", "--bars", "method", "mean_px",
                                             "--where", "category=RE", "--x-label", "px", "--title", "RE",
                                             "--size", "1000x500"};
  EXPECT_EQ(command, expected);
}

TEST_F(CsvPlotTest, DrawsAPngOfTheRequestedSizeFromTheCsv) {
  ASSERT_FALSE(plotScriptPath().empty()) << "deep_ois is not on ROS_PACKAGE_PATH";
  const PlotOutcome outcome = plotCsv(plot_, dir_ + "/lens.csv", dir_ + "/lens.png");
  ASSERT_TRUE(outcome.written) << outcome.problem;
  const cv::Mat png = cv::imread(dir_ + "/lens.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 640);
  EXPECT_EQ(png.rows, 360);
  // Ink: the axes, labels and two curves darken a good share of the white canvas.
  const double mean_brightness = cv::mean(png)[0];
  EXPECT_LT(mean_brightness, 250.0);
  EXPECT_EQ(describePlot(outcome, dir_ + "/lens.csv", dir_ + "/lens.png"), "wrote " + dir_ + "/lens.png");
}

TEST_F(CsvPlotTest, WithoutMatplotlibTheCsvStaysAndTheReasonIsGiven) {
  // A matplotlib package that fails to import, found before Debian's.
  fs::create_directories(dir_ + "/shadow/matplotlib");
  std::ofstream(dir_ + "/shadow/matplotlib/__init__.py") << "raise ImportError('hidden by the test')\n";
  setenv("PYTHONPATH", (dir_ + "/shadow").c_str(), 1);
  std::ofstream(dir_ + "/lens.png") << "stale";  // a PNG of an earlier run must not pass for this one
  const std::string csv_before = readFile(dir_ + "/lens.csv");
  const PlotOutcome outcome = plotCsv(plot_, dir_ + "/lens.csv", dir_ + "/lens.png");
  EXPECT_FALSE(outcome.written);
  EXPECT_NE(outcome.problem.find("python3-matplotlib"), std::string::npos) << outcome.problem;
  EXPECT_FALSE(fs::exists(dir_ + "/lens.png"));
  EXPECT_EQ(readFile(dir_ + "/lens.csv"), csv_before);
  const std::string line = describePlot(outcome, dir_ + "/lens.csv", dir_ + "/lens.png");
  EXPECT_NE(line.find("the data is in " + dir_ + "/lens.csv"), std::string::npos) << line;
}

TEST_F(CsvPlotTest, AColumnTheCsvLacksIsAProblemNotAThrow) {
  plot_.curves.push_back({"missing_px", "missing"});
  const PlotOutcome outcome = plotCsv(plot_, dir_ + "/lens.csv", dir_ + "/lens.png");
  EXPECT_FALSE(outcome.written);
  EXPECT_NE(outcome.problem.find("exit status 1"), std::string::npos) << outcome.problem;
}

TEST_F(CsvPlotTest, AnUnwritableCsvIsReturnedByWriteAndPlot) {
  const PlotOutcome outcome =
      writeAndPlotCsv(plot_, {{"t_s", {0.0}}, {"logged_px", {1.0}}}, "/nonexistent_dir/x.csv", dir_ + "/x.png");
  EXPECT_FALSE(outcome.written);
  EXPECT_NE(outcome.problem.find("cannot write"), std::string::npos) << outcome.problem;
}

}  // namespace
}  // namespace deep_ois
