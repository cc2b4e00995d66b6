// The evaluation report's comments on its own figures (issue 23 #8, #13): a compensation that
// beats the non-OIS twin is called implausible, a row left out of the table is named.
#include <gtest/gtest.h>

#include <string>

#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/tools/support/evaluation_report.h"

namespace deep_ois {
namespace {

void addPair(EvaluationReport& report, const std::string& method, double distance_px) {
  constexpr double kIdentityPx = 5.0;
  report.table.addCapped(method, "RE", distance_px, kIdentityPx);
  PairScore pair;
  pair.method = method;
  pair.category = "RE";
  pair.distance_px = distance_px;
  pair.identity_px = kIdentityPx;
  pair.scored_px = distance_px;
  report.pairs.push_back(pair);
}

// Measured with a wrong gyro config: 144-151 % of the gap, printed without a word.
TEST(EvaluationReport, ACompensationBeyondTheNonOisTwinIsCalledImplausible) {
  EvaluationReport report;
  report.method_scopes = {{kGyroNonOisMethod, kNonOisTwinPairs},
                          {kGyroOisMethod, kOisCameraPairs},
                          {"SIFT + RANSAC", kBenchmarkPairs},
                          {"stabiliser model, m.yaml", kOisCameraPairs},
                          {"stabiliser model, good.yaml", kOisCameraPairs}};
  addPair(report, kGyroOisMethod, 1.0);
  addPair(report, kGyroNonOisMethod, 0.5);
  addPair(report, "SIFT + RANSAC", 0.2);                 // sees the images: may beat the twin
  addPair(report, "stabiliser model, m.yaml", 0.25);     // 150 %
  addPair(report, "stabiliser model, good.yaml", 0.52);  // 96 %
  const auto gaps = report.gapClosed();
  ASSERT_EQ(gaps.size(), 3u);
  EXPECT_FALSE(gaps[0].beyond_twin);  // SIFT
  EXPECT_TRUE(gaps[1].beyond_twin);
  EXPECT_NEAR(gaps[1].capped_percent, 150.0, 1e-9);
  EXPECT_FALSE(gaps[2].beyond_twin);
  const std::string markdown = report.markdown();
  const std::size_t line =
      markdown.find("- stabiliser model, m.yaml: 150.0 % capped, 150.0 % uncapped");
  ASSERT_NE(line, std::string::npos) << markdown;
  const std::string rest = markdown.substr(line, markdown.find('\n', line) - line);
  EXPECT_NE(rest.find("implausible"), std::string::npos) << rest;
  EXPECT_NE(rest.find("time offset or readout"), std::string::npos) << rest;
  EXPECT_EQ(markdown.find("implausible"), markdown.rfind("implausible")) << markdown;
}

// `evaluate --camera non-ois --stabiliser M.yaml`: the stabiliser row has no pair in scope.
TEST(EvaluationReport, NamesRowsThatNoPairWasInScopeFor) {
  EvaluationReport report;
  report.method_scopes = {{kGyroNonOisMethod, kBenchmarkPairs},
                          {kGyroOisMethod, kOisCameraPairs},
                          {kGyroMethod, kUnspecifiedCameraPairs},
                          {"stabiliser model, m.yaml", kOisCameraPairs}};
  addPair(report, kGyroNonOisMethod, 0.5);
  EXPECT_EQ(report.rowsWithoutPairs(), std::vector<std::string>{"stabiliser model, m.yaml"});
  EXPECT_NE(report.markdown().find("- stabiliser model, m.yaml: no pair of these recordings is in "
                                   "its scope"),
            std::string::npos)
      << report.markdown();
}

}  // namespace
}  // namespace deep_ois
