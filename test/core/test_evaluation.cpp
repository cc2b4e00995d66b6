#include <gtest/gtest.h>

#include <cmath>

#include "deep_ois/core/evaluation_table.h"
#include "deep_ois/core/geometry_distance.h"
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
}

}  // namespace
}  // namespace deep_ois
