// OutputShedding: the compensation's graceful overload rule (issue 40 item 3). A late pair sheds
// the costliest optional output first, each further late pair one more; a calm stretch gives them
// back one at a time, the cheapest first; the order never changes while something is shed.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "deep_ois/core/common/output_shedding.h"

namespace deep_ois {
namespace {

constexpr std::size_t kColour = 0, kAligned = 1, kGhost = 2;

OutputShedding measuredOutputs() {
  OutputShedding shedding({"colour", "aligned", "ghost"});
  shedding.measured(kColour, 0.0008);
  shedding.measured(kAligned, 0.0011);
  shedding.measured(kGhost, 0.0020);
  return shedding;
}

TEST(OutputShedding, NothingIsShedWhileThePairsAreOnTime) {
  OutputShedding shedding = measuredOutputs();
  for (int k = 0; k < 100; ++k) EXPECT_EQ(shedding.beforePair(0.01 * (k % 12)), 0u);  // up to 0.11 s
  for (std::size_t i = 0; i < 3; ++i) EXPECT_FALSE(shedding.shed(i));
  EXPECT_EQ(shedding.describeShed(), "nothing");
}

TEST(OutputShedding, ALatePairShedsTheCostliestFirstThenOneMorePerLatePair) {
  OutputShedding shedding = measuredOutputs();
  EXPECT_EQ(shedding.beforePair(0.2), 1u);
  EXPECT_TRUE(shedding.shed(kGhost));
  EXPECT_FALSE(shedding.shed(kAligned));
  EXPECT_FALSE(shedding.shed(kColour));
  EXPECT_EQ(shedding.beforePair(0.3), 2u);
  EXPECT_TRUE(shedding.shed(kGhost));
  EXPECT_TRUE(shedding.shed(kAligned));
  EXPECT_FALSE(shedding.shed(kColour));
  EXPECT_EQ(shedding.beforePair(0.3), 3u);
  EXPECT_EQ(shedding.beforePair(0.4), 3u);  // nothing more to shed: the caller's own rule drops
  EXPECT_EQ(shedding.describeShed(), "ghost, aligned, colour");
  EXPECT_EQ(shedding.describeOrder(), "ghost 2.00 ms, aligned 1.10 ms, colour 0.80 ms");
  EXPECT_EQ(shedding.escalations(), 3u);
}

TEST(OutputShedding, ACalmStretchGivesTheCheapestBackFirst) {
  OutputShedding shedding = measuredOutputs();
  for (int k = 0; k < 3; ++k) shedding.beforePair(0.5);
  ASSERT_EQ(shedding.level(), 3u);
  for (int k = 0; k < 29; ++k) EXPECT_EQ(shedding.beforePair(0.01), 3u);
  EXPECT_EQ(shedding.beforePair(0.01), 2u);
  EXPECT_FALSE(shedding.shed(kColour));
  EXPECT_TRUE(shedding.shed(kAligned));
  // A pair between the two thresholds starts the calm stretch over.
  for (int k = 0; k < 29; ++k) shedding.beforePair(0.01);
  shedding.beforePair(0.08);
  for (int k = 0; k < 29; ++k) EXPECT_EQ(shedding.beforePair(0.01), 2u);
  EXPECT_EQ(shedding.beforePair(0.01), 1u);
  EXPECT_FALSE(shedding.shed(kAligned));
  EXPECT_TRUE(shedding.shed(kGhost));
  for (int k = 0; k < 30; ++k) shedding.beforePair(0.0);
  EXPECT_EQ(shedding.level(), 0u);
}

TEST(OutputShedding, TheOrderIsFixedWhileSomethingIsShedAndFollowsTheCostsAfter) {
  OutputShedding shedding = measuredOutputs();
  shedding.beforePair(0.2);
  ASSERT_TRUE(shedding.shed(kGhost));
  // The colour image turns costly (e.g. a larger grid) while the ghost is shed.
  for (int k = 0; k < 40; ++k) shedding.measured(kColour, 0.005);
  EXPECT_TRUE(shedding.shed(kGhost));
  EXPECT_FALSE(shedding.shed(kColour));
  for (int k = 0; k < 30; ++k) shedding.beforePair(0.0);
  ASSERT_EQ(shedding.level(), 0u);
  shedding.beforePair(0.2);
  EXPECT_TRUE(shedding.shed(kColour)) << shedding.describeOrder();
  EXPECT_FALSE(shedding.shed(kGhost));
}

TEST(OutputShedding, OnlyWantedOutputsCountAsShedAndUnmeasuredOnesGoLast) {
  OutputShedding shedding({"colour", "aligned", "ghost"});
  shedding.measured(kAligned, 0.001);
  shedding.beforePair(0.2);
  EXPECT_TRUE(shedding.shed(kAligned, true));
  shedding.beforePair(0.2);
  EXPECT_TRUE(shedding.shed(kColour, false));  // shed, but nobody listens: not counted
  EXPECT_EQ(shedding.shedCount(kAligned), 1u);
  EXPECT_EQ(shedding.shedCount(kColour), 0u);
  EXPECT_EQ(shedding.describeCounts(), "colour 0, aligned 1, ghost 0 of 2 pairs (2 times one more shed)");
}

TEST(OutputShedding, BadOptionsAreRefusedNamingTheField) {
  OutputSheddingOptions options;
  options.restore_below_s = 0.2;
  try {
    OutputShedding shedding({"colour"}, options);
    FAIL() << "accepted restore_below_s above shed_above_s";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("restore_below_s"), std::string::npos) << e.what();
  }
  EXPECT_THROW(OutputShedding({}, OutputSheddingOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
