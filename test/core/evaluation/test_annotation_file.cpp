// The annotation file reader: the agreed format, and clear errors naming file and line.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "deep_ois/core/evaluation/annotation_file.h"

namespace deep_ois {
namespace {

AnnotationFile parse(const std::string& text) {
  std::istringstream in(text);
  return parseAnnotations(in, "pairs.csv");
}

// The message of the error parsing `text` raises ("" when it parses).
std::string errorOf(const std::string& text) {
  try {
    parse(text);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

const std::string kHeader = "stamp_a,stamp_b,x_a,y_a,x_b,y_b,category\n";

TEST(AnnotationFile, ReadsPairsOfPointsByStamps) {
  const AnnotationFile file = parse(
      "\xEF\xBB\xBF# cc9pro, far background points checked on 4x crops\r\n"
      "stamp_a,stamp_b,x_a,y_a,x_b,y_b,category\r\n"
      "1594117812.123456789,1594117812.156789012,10.5,20.25,11.5,21.0,real\r\n"
      "\n"
      "# the second pair\n"
      "1594117813.5,1594117813.533333333, 100 , 200 ,101,199,LT\n"
      "1594117812.123456789,1594117812.156789012,300,40,301.75,41,real\n");
  EXPECT_EQ(file.path, "pairs.csv");
  ASSERT_EQ(file.pairs.size(), 2u);
  EXPECT_EQ(file.pointCount(), 3u);
  const AnnotatedPair& first = file.pairs[0];
  EXPECT_EQ(first.stamp_a_ns, 1594117812123456789LL);
  EXPECT_EQ(first.stamp_b_ns, 1594117812156789012LL);
  EXPECT_EQ(first.category, "real");
  ASSERT_EQ(first.points_a_px.size(), 2u);  // rows of one pair need not be adjacent
  EXPECT_EQ(first.points_a_px[1], Eigen::Vector2d(300, 40));
  EXPECT_EQ(first.points_b_px[1], Eigen::Vector2d(301.75, 41));
  EXPECT_EQ(first.lines, (std::vector<int>{3, 7}));
  const AnnotatedPair& second = file.pairs[1];
  EXPECT_EQ(second.stamp_a_ns, 1594117813500000000LL);  // fewer decimals are padded
  EXPECT_EQ(second.points_a_px[0], Eigen::Vector2d(100, 200));
  EXPECT_EQ(second.category, "LT");
}

TEST(AnnotationFile, StampsRoundTripToTheNanosecond) {
  std::int64_t ns = 0;
  ASSERT_TRUE(parseStampNs("1594117812.000000001", ns));
  EXPECT_EQ(ns, 1594117812000000001LL);
  EXPECT_EQ(formatStampNs(ns), "1594117812.000000001");
  ASSERT_TRUE(parseStampNs("7", ns));
  EXPECT_EQ(formatStampNs(ns), "7.000000000");
  for (const char* bad :
       {"", "-1.5", "1.", ".5", "1.0000000001", "1e9", "12a.3", "99999999999.0", " 1.0"}) {
    EXPECT_FALSE(parseStampNs(bad, ns)) << bad;
  }
}

TEST(AnnotationFile, MalformedFilesNameTheFileAndLine) {
  const std::string row = "1.000000000,1.033333333,1,2,3,4,RE\n";
  EXPECT_EQ(errorOf(""),
            "pairs.csv: no header line 'stamp_a,stamp_b,x_a,y_a,x_b,y_b,category' (empty file?)");
  EXPECT_EQ(errorOf(kHeader), "pairs.csv: no annotated point after the header");
  EXPECT_NE(errorOf("# c\nstamp_a,stamp_b,x,y,x_b,y_b,category\n")
                .find("pairs.csv:2: expected the header"),
            std::string::npos);
  EXPECT_EQ(errorOf(kHeader + row + "1.0,2.0,1,2,3,RE\n"),
            "pairs.csv:3: expected 7 comma-separated fields "
            "(stamp_a,stamp_b,x_a,y_a,x_b,y_b,category), got 6");
  EXPECT_EQ(errorOf(kHeader + "1.0,2.0,1,2,3,4,RE,extra\n").substr(0, 13), "pairs.csv:2: ");
  EXPECT_EQ(errorOf(kHeader + "1.0,2.0,1,2,3,4,\n"), "pairs.csv:2: the category is empty");
  EXPECT_EQ(errorOf(kHeader + "1.0x,2.0,1,2,3,4,RE\n"),
            "pairs.csv:2: stamp_a '1.0x' is not seconds with up to 9 decimals");
  EXPECT_EQ(errorOf(kHeader + "1.0,2.0000000001,1,2,3,4,RE\n"),
            "pairs.csv:2: stamp_b '2.0000000001' is not seconds with up to 9 decimals");
  EXPECT_EQ(
      errorOf(kHeader + "2.0,1.0,1,2,3,4,RE\n"),
      "pairs.csv:2: stamp_b 1.0 is not later than stamp_a 2.0 (frame a is the earlier frame)");
  EXPECT_EQ(errorOf(kHeader + "1.0,2.0,1,two,3,4,RE\n"),
            "pairs.csv:2: y_a 'two' is not a finite number");
  EXPECT_EQ(errorOf(kHeader + "1.0,2.0,1,2,nan,4,RE\n"),
            "pairs.csv:2: x_b 'nan' is not a finite number");
  EXPECT_EQ(errorOf(kHeader + row + "# comment\n" + "1.000000000,1.033333333,5,6,7,8,LT\n"),
            "pairs.csv:4: category 'LT' differs from 'RE' given for this pair on line 2");
}

TEST(AnnotationFile, ReadsAFileAndNamesAMissingOne) {
  const std::string path = ::testing::TempDir() + "/annotations.csv";
  std::ofstream(path) << kHeader << "5.5,5.6,1,2,3,4,real\n";
  const AnnotationFile file = readAnnotationFile(path);
  EXPECT_EQ(file.path, path);
  ASSERT_EQ(file.pairs.size(), 1u);
  try {
    readAnnotationFile(path + ".missing");
    FAIL() << "no error for a missing file";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), path + ".missing: cannot open the annotation file");
  }
}

}  // namespace
}  // namespace deep_ois
