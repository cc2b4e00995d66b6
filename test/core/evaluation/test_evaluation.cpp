// The evaluator's pure parts on hand-made cases: the geometry distance of homographies and of grid
// flows (with the grid <-> camera scaling), the capping rule, the table and report.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/evaluation/results_table.h"
#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/grid_flow_sampling.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/tools/support/evaluation_plots.h"
#include "deep_ois/tools/support/evaluation_report.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

TEST(GeometryDistance, UsesThePatchOfEachPointsRow) {
  // Two patches over 100 rows: the top one shifts right by 1 px, the bottom one down by 2 px.
  Eigen::Matrix3d top = Eigen::Matrix3d::Identity(), bottom = Eigen::Matrix3d::Identity();
  top(0, 2) = 1.0;
  bottom(1, 2) = 2.0;
  const std::vector<Eigen::Vector2d> a = {{10, 10}, {10, 80}};
  const std::vector<Eigen::Vector2d> b = {{11, 10}, {10, 85}};  // exact for the top, 3 px off below
  EXPECT_DOUBLE_EQ(geometryDistance(a, b, {top, bottom}, 100), (0.0 + 3.0) / 2.0);
  EXPECT_DOUBLE_EQ(geometryDistance(a, b, {Eigen::Matrix3d::Identity()}, 100), (1.0 + 5.0) / 2.0);
  EXPECT_TRUE(std::isnan(geometryDistance({}, {}, {top}, 100)));
  EXPECT_THROW(geometryDistance(a, {b[0]}, {top}, 100), std::invalid_argument);
  EXPECT_THROW(geometryDistance(a, b, std::vector<Eigen::Matrix3d>{}, 100), std::invalid_argument);
}

TEST(GeometryDistance, AppliesTheLensModelAroundRotationHomographies) {
  Eigen::Matrix3d K;
  K << 200, 0, 100, 0, 200, 75, 0, 0, 1;
  const CameraModel pinhole(200, 150, K), lens(200, 150, K, {-0.2, 0.05, 0.001, -0.001, 0.0});
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
  shift(0, 2) = 3.0;  // 3 px right, in undistorted pixels
  const std::vector<Eigen::Vector2d> a = {{20, 20}, {100, 75}, {180, 140}};
  std::vector<Eigen::Vector2d> b;
  for (const auto& p : a) b.push_back(lens.distort(lens.undistort(p) + Eigen::Vector2d(3.0, 0.0)));
  // Without distortion the camera overload is the plain one.
  EXPECT_DOUBLE_EQ(geometryDistance(a, b, {shift}, pinhole), geometryDistance(a, b, {shift}, 150));
  // With it, the shift applied in undistorted pixels lands exactly on b.
  EXPECT_NEAR(geometryDistance(a, b, {shift}, lens), 0.0, 1e-6);
  EXPECT_GT(geometryDistance(a, b, {shift}, 150), 0.05);  // the raw-pixel reading misses
  // Identity stays identity through the lens model.
  EXPECT_NEAR(geometryDistance(a, b, {Eigen::Matrix3d::Identity()}, lens),
              geometryDistance(a, b, {Eigen::Matrix3d::Identity()}, 150), 1e-6);
}

// A camera of 8x6 pixels and a grid of 4x3: s = 2 camera pixels per grid pixel.
TEST(GridFlow, ScalesGridPixelsToCameraPixels) {
  const cv::Size camera(8, 6);
  const cv::Mat constant(3, 4, CV_32FC2, cv::Scalar(0.5, -1.0));  // grid pixels
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(2.0, 2.0), WorkingGrid(camera, constant.size()).scale(), 0.0);
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(3.3, 2.7), Eigen::Vector2d(7, 5)}) {
    EXPECT_MATRIX_NEAR(Eigen::Vector2d(1.0, -2.0), sampleGridFlow(constant, camera, p), 1e-12);
  }
  // The paper's distance: a = (1, 1) lands on b exactly; (5, 4) lands on (6, 2), 3 px from (6, 5).
  const std::vector<Eigen::Vector2d> a = {{1, 1}, {5, 4}}, b = {{2, -1}, {6, 5}};
  EXPECT_DOUBLE_EQ(geometryDistanceOfGridFlow(a, b, constant, camera), (0.0 + 3.0) / 2.0);
  EXPECT_THROW(geometryDistanceOfGridFlow(a, {b[0]}, constant, camera), std::invalid_argument);
  EXPECT_THROW(sampleGridFlow(cv::Mat(3, 4, CV_32FC1), camera, a[0]), std::invalid_argument);
}

TEST(GridFlow, SamplesBilinearlyAtTheGridPositionOfACameraPixel) {
  // u = grid x, v = 10 * grid y: linear, so bilinear sampling is exact inside the grid.
  const cv::Size camera(8, 6);
  cv::Mat ramp(3, 4, CV_32FC2);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) ramp.at<cv::Vec2f>(y, x) = cv::Vec2f(x, 10.0f * y);
  // Camera pixel (3, 2) is grid ((3.5 / 2) - 0.5, (2.5 / 2) - 0.5) = (1.25, 0.75): u = 1.25 grid px
  // = 2.5 camera px, v = 7.5 grid px = 15 camera px.
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(2.5, 15.0), sampleGridFlow(ramp, camera, {3, 2}), 1e-6);
  // Camera pixel (0, 0) is grid (-0.25, -0.25): clamped to the corner grid pixel, value (0, 0).
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(0.0, 0.0), sampleGridFlow(ramp, camera, {0, 0}), 1e-12);
  // The bottom-right camera pixel (7, 5) is grid (3.25, 2.25): clamped to (3, 2).
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(6.0, 40.0), sampleGridFlow(ramp, camera, {7, 5}), 1e-6);
}

TEST(GridFlow, TheCameraResolutionFlowAgreesWithPointSampling) {
  std::mt19937 random(3);
  std::uniform_real_distribution<float> value(-3.0f, 3.0f);
  cv::Mat grid(9, 12, CV_32FC2);
  for (int y = 0; y < grid.rows; ++y)
    for (int x = 0; x < grid.cols; ++x)
      grid.at<cv::Vec2f>(y, x) = cv::Vec2f(value(random), value(random));
  for (const cv::Size camera : {cv::Size(36, 27), cv::Size(12, 9), cv::Size(30, 20)}) {
    const cv::Mat dense = gridFlowToCameraFlow(grid, camera);
    ASSERT_EQ(dense.size(), camera);
    ASSERT_EQ(dense.type(), CV_32FC2);
    double worst = 0.0;
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const cv::Vec2f d = dense.at<cv::Vec2f>(y, x);
        worst = std::max(worst, (Eigen::Vector2d(d[0], d[1]) -
                                 sampleGridFlow(grid, camera, Eigen::Vector2d(x, y)))
                                    .norm());
      }
    }
    EXPECT_LT(worst, 1e-3) << camera;  // cv::resize's float interpolation vs double
  }
}

TEST(GridFlow, AGridFlowScoresLikeTheHomographiesItWasRenderedFrom) {
  // Two patches of a 160x120 camera: a rotation-like homography on top, a shift below, rendered
  // on the half-resolution working grid the nodelet would publish.
  Eigen::Matrix3d K;
  K << 150, 0, 80, 0, 150, 60, 0, 0, 1;
  const CameraModel camera(160, 120, K);
  Eigen::Matrix3d top = Eigen::Matrix3d::Identity(), bottom = Eigen::Matrix3d::Identity();
  top(0, 2) = 2.0;
  top(1, 2) = -1.0;
  bottom(0, 2) = -1.5;
  const HomographyFlowRenderer renderer(camera, cv::Size(80, 60), 2);
  cv::Mat grid;
  renderer.render({top, bottom}, grid);
  // Points on the grid's sample positions of each patch (camera (2g + 0.5)): flows are exact there.
  const std::vector<Eigen::Vector2d> a = {{10.5, 10.5}, {70.5, 40.5}, {30.5, 90.5}, {150.5, 110.5}};
  const std::vector<Eigen::Vector2d> b = {{13, 9}, {72, 40}, {29, 91}, {149, 110}};
  EXPECT_NEAR(geometryDistanceOfGridFlow(a, b, grid, cv::Size(160, 120)),
              geometryDistance(a, b, {top, bottom}, camera), 1e-5);
}

TEST(AlignmentEstimate, EveryKindOfMotionIsScoredByTheSameDistance) {
  Eigen::Matrix3d K;
  K << 100, 0, 50, 0, 100, 40, 0, 0, 1;
  const CameraModel camera(100, 80, K);
  FramePairContext pair;
  pair.camera = &camera;
  pair.points_a_px = {{10, 10}, {60, 70}};
  pair.points_b_px = {{12, 11}, {61, 71}};
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
  shift(0, 2) = 2.0;
  shift(1, 2) = 1.0;  // exact for the first point, 1 px off in x for the second
  const double expected = 0.5;
  EXPECT_DOUBLE_EQ(estimateDistance(AlignmentEstimate::rawHomography(shift), pair), expected);
  EXPECT_DOUBLE_EQ(
      estimateDistance(AlignmentEstimate::patchHomographies({shift, shift, shift}), pair),
      expected);
  const cv::Mat grid(40, 50, CV_32FC2, cv::Scalar(1.0, 0.5));  // s = 2: (2, 1) camera pixels
  EXPECT_NEAR(estimateDistance(AlignmentEstimate::gridFlow(grid), pair), expected, 1e-12);
  EXPECT_TRUE(std::isnan(estimateDistance(AlignmentEstimate::failed("too few matches"), pair)));
  // The dense camera flows of the three agree, and a failure is a zero flow.
  const cv::Mat from_h = estimateCameraFlow(AlignmentEstimate::rawHomography(shift), camera);
  const cv::Mat from_grid = estimateCameraFlow(AlignmentEstimate::gridFlow(grid), camera);
  EXPECT_LT(cv::norm(from_h, from_grid, cv::NORM_INF), 1e-5);
  EXPECT_EQ(cv::norm(estimateCameraFlow(AlignmentEstimate::failed("x"), camera), cv::NORM_INF),
            0.0);
}

TEST(FlowWarp, BringsFrameBOntoFrameA) {
  cv::Mat b(20, 30, CV_8UC3);
  for (int y = 0; y < b.rows; ++y)
    for (int x = 0; x < b.cols; ++x) b.at<cv::Vec3b>(y, x) = cv::Vec3b(x * 8, y * 12, 7);
  const cv::Mat flow(20, 30, CV_32FC2,
                     cv::Scalar(2.0, 1.0));  // frame a's pixel p is b's p + (2, 1)
  const cv::Mat warped = warpFrameBOntoA(b, flow);
  EXPECT_EQ(warped.at<cv::Vec3b>(5, 4), b.at<cv::Vec3b>(6, 6));
  EXPECT_EQ(warped.at<cv::Vec3b>(19, 29), cv::Vec3b(0, 0, 0));  // lands outside frame b
  EXPECT_THROW(warpFrameBOntoA(b, cv::Mat(10, 10, CV_32FC2)), std::invalid_argument);
}

TEST(EvaluationTable, CapsMeansAndOrdersLikeThePaper) {
  EXPECT_DOUBLE_EQ(capAtIdentity(5.0, 2.0), 2.0);
  EXPECT_DOUBLE_EQ(capAtIdentity(1.0, 2.0), 1.0);
  EvaluationTable table;
  table.add("gyro", "LL", 1.0);
  table.add("gyro", "RE", 2.0);
  table.add("gyro", "RE", 4.0);
  table.add("identity", "MF", 7.0);
  EXPECT_DOUBLE_EQ(table.mean("gyro", "RE"), 3.0);
  EXPECT_EQ(table.count("gyro", "RE"), 2u);
  EXPECT_TRUE(std::isnan(table.mean("gyro", "MF")));
  EXPECT_DOUBLE_EQ(table.average("gyro"), (1.0 + 3.0) / 2.0);  // categories without pairs left out
  table.orderCategories({"RE", "LT", "LL", "MF"});
  EXPECT_EQ(table.categories(), (std::vector<std::string>{"RE", "LL", "MF"}));
  const std::string markdown = table.markdown();
  EXPECT_NE(markdown.find("| method | RE | LL | MF | Avg |"), std::string::npos) << markdown;
  EXPECT_NE(markdown.find("| gyro | 3.000 | 1.000 | - | 2.000 |"), std::string::npos) << markdown;
  EXPECT_NE(table.csv().find("\"identity\",MF,1,7"), std::string::npos) << table.csv();
  table.orderMethods({"identity", "gyro"});
  EXPECT_EQ(table.methods(), (std::vector<std::string>{"identity", "gyro"}));
}

TEST(EvaluationTable, ThePapersCappingRuleAndFailures) {
  // Three pairs of one category with identity errors 2, 4 and 6 px. The method misses the first
  // by 1 px (kept), the second by 9 px (worse than not aligning: capped at 4), and gives no
  // estimate for the third (scored as identity, 6).
  EvaluationTable table;
  EXPECT_DOUBLE_EQ(table.addCapped("SIFT", "LT", 1.0, 2.0), 1.0);
  EXPECT_DOUBLE_EQ(table.addCapped("SIFT", "LT", 9.0, 4.0), 4.0);
  table.addFailure("SIFT", "LT", 6.0);
  EXPECT_DOUBLE_EQ(table.mean("SIFT", "LT"), (1.0 + 4.0 + 6.0) / 3.0);
  EXPECT_EQ(table.count("SIFT", "LT"), 3u);
  EXPECT_EQ(table.capped("SIFT", "LT"), 1u);
  EXPECT_EQ(table.failures("SIFT", "LT"), 1u);
  // Equal to identity is not "worse": not counted as capped.
  table.addCapped("SIFT", "RE", 2.0, 2.0);
  EXPECT_EQ(table.capped("SIFT", "RE"), 0u);
  // Never above identity, so a capped method's mean never exceeds the identity row's.
  EXPECT_NE(table.csv().find("\"SIFT\",LT,3,3.66667,1,1"), std::string::npos) << table.csv();
  EXPECT_NE(table.csv().find("\"SIFT\",Avg,,"), std::string::npos) << table.csv();
}

TEST(EvaluationReport, NotesFailuresCappingAndErrorsUnderTheTable) {
  EvaluationReport report;
  report.table.addCapped("identity", "RE", 2.0, 2.0);
  report.table.addFailure("ORB + RANSAC", "RE", 2.0);
  ++report.failure_reasons["ORB + RANSAC"]["too few matches (< 8)"];
  report.table.addCapped("gyro", "RE", 3.0, 2.0);
  report.recordings.push_back({"good.bag", 1, 0, {}, "", {}});
  report.recordings.push_back({"bad.bag", 0, 0, {}, "bad.bag: cannot open the bag", {}});
  report.errors.push_back(
      "pairs.csv:7: pair 1.000000000 -> 2.000000000 matches no frame of the bags given");
  const std::string markdown = report.markdown();
  EXPECT_NE(markdown.find("- ORB + RANSAC: 1 pairs; 1 without an estimate, scored as identity (too "
                          "few matches (< 8): 1)"),
            std::string::npos)
      << markdown;
  EXPECT_NE(markdown.find("- gyro: 1 pairs; 1 worse than identity, capped"), std::string::npos)
      << markdown;
  EXPECT_NE(markdown.find("bad.bag: cannot open the bag"), std::string::npos) << markdown;
  EXPECT_NE(markdown.find("pairs.csv:7:"), std::string::npos) << markdown;
  EXPECT_FALSE(report.complete());
  EXPECT_EQ(report.failedRecordings(), 1u);
  const std::string text = report.json();
  const nlohmann::json json = nlohmann::json::parse(text);
  const nlohmann::json& methods = json.at("methods");
  const auto orb = std::find_if(methods.begin(), methods.end(), [](const nlohmann::json& m) {
    return m.at("name") == "ORB + RANSAC";
  });
  ASSERT_NE(orb, methods.end()) << text;
  EXPECT_DOUBLE_EQ(orb->at("avg_px").get<double>(), 2.0) << text;
  EXPECT_EQ(orb->at("failure_reasons").at("too few matches (< 8)").get<int>(), 1) << text;
  EXPECT_EQ(orb->at("categories").at("RE").at("failed").get<int>(), 1) << text;
  ASSERT_EQ(json.at("recordings").size(), 2u) << text;
  EXPECT_TRUE(json.at("recordings")[0].at("error").is_null()) << text;
  EXPECT_EQ(json.at("recordings")[1].at("error"), "bad.bag: cannot open the bag") << text;
  EXPECT_EQ(json.at("errors").size(), 1u) << text;
}

TEST(EvaluationReport, ReportsUncappedMeansAndTheGapClosed) {
  EvaluationReport report;
  // Two pairs in RE: the OIS gyro is worse than identity on the second (capped there).
  auto pair = [&report](const std::string& method, double distance, double identity) {
    report.table.addCapped(method, "RE", distance, identity);
    report.pairs.push_back({0, 0, 0, "RE", method, distance, identity,
                            std::min(distance, identity), ""});
  };
  pair("identity", 2.0, 2.0);
  pair("identity", 2.0, 2.0);
  pair(kGyroOisMethod, 1.0, 2.0);
  pair(kGyroOisMethod, 5.0, 2.0);
  pair(kGyroNonOisMethod, 0.2, 2.0);
  pair(kGyroNonOisMethod, 0.2, 2.0);
  pair("model", 0.4, 2.0);
  pair("model", 0.6, 2.0);
  EXPECT_DOUBLE_EQ(report.uncappedTable().mean(kGyroOisMethod, "RE"), 3.0);
  EXPECT_DOUBLE_EQ(report.table.mean(kGyroOisMethod, "RE"), 1.5);
  const auto gaps = report.gapClosed();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].method, "model");
  EXPECT_NEAR(gaps[0].capped_percent, 100.0 * (1.5 - 0.5) / (1.5 - 0.2), 1e-9);
  EXPECT_NEAR(gaps[0].uncapped_percent, 100.0 * (3.0 - 0.5) / (3.0 - 0.2), 1e-9);
  const std::string markdown = report.markdown();
  EXPECT_NE(markdown.find("Uncapped"), std::string::npos) << markdown;
  EXPECT_NE(markdown.find("- model: 76.9 % capped, 89.3 % uncapped"), std::string::npos) << markdown;
}

TEST(EvaluationPlots, DrawsGhostGrids) {
  GhostSample sample;
  sample.category = "RE";
  sample.label = "pair 1";
  sample.panels.push_back(
      {"identity", cv::Mat(30, 40, CV_8UC3, cv::Scalar(10, 20, 30)), 2.0, false, false});
  sample.panels.push_back(
      {"gyro", cv::Mat(30, 40, CV_8UC3, cv::Scalar(40, 50, 60)), 0.5, false, false});
  const cv::Mat grid = drawGhostGrid("ghosts", {sample, sample}, {"identity", "gyro", "absent"});
  ASSERT_FALSE(grid.empty());
  EXPECT_EQ(grid.cols, 3 * (40 + 4) + 4);  // one column per method, blank where absent
  EXPECT_TRUE(drawGhostGrid("ghosts", {}, {"identity"}).empty());
  // The centre half, twice as large, nearest neighbour.
  cv::Mat image(4, 4, CV_8UC1);
  for (int k = 0; k < 16; ++k) image.data[k] = static_cast<unsigned char>(k);
  const cv::Mat magnified = magnifyCentre(image, 2);
  EXPECT_EQ(magnified.size(), image.size());
  EXPECT_EQ(magnified.at<unsigned char>(0, 0), image.at<unsigned char>(1, 1));
  EXPECT_EQ(magnified.at<unsigned char>(3, 3), image.at<unsigned char>(2, 2));
}

}  // namespace
}  // namespace deep_ois
