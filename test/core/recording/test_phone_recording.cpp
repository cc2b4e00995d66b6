// The phone recording parsers (gyro CSV, frame stamps): no data needed.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/recording/phone_recording.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

// Parser errors need no data: they must name the file, the line and the problem.
TEST(PhoneRecordingParse, ReadsGyroRowsAndStamps) {
  std::istringstream gyro("0.1,-0.2,0.3,100.0\n\n0.4,0.5,-0.6,100.0025\r\n");
  const std::vector<ImuSample> samples = parseGyroCsv(gyro, "gyro.txt");
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_DOUBLE_EQ(samples[1].stamp_s, 100.0025);
  EXPECT_MATRIX_NEAR(Eigen::Vector3d(0.4, 0.5, -0.6), samples[1].angular_velocity_rad_s, 0.0);
  std::istringstream stamps("4.328040426246000454e+06\n4.328040459559000097e+06\n\n");
  const std::vector<double> frames = parseFrameStamps(stamps, "framestamp.txt");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_DOUBLE_EQ(frames[0], 4328040.426246);
}

// Returns the message of the RecordingFormatError `parse` throws, or "" if none.
template <typename Parse>
std::string errorOf(const std::string& text, Parse parse, int* line = nullptr) {
  std::istringstream in(text);
  try {
    parse(in, "file.txt");
  } catch (const RecordingFormatError& e) {
    if (line) *line = e.line();
    return e.what();
  }
  return "";
}

TEST(PhoneRecordingParse, ReportsFileLineAndProblem) {
  auto gyro = [](std::istream& in, const std::string& name) { parseGyroCsv(in, name); };
  auto stamps = [](std::istream& in, const std::string& name) { parseFrameStamps(in, name); };
  int line = 0;
  EXPECT_EQ(errorOf("1,2,3,4\n1,2,3\n", gyro, &line),
            "file.txt:2: expected 4 comma-separated fields wx,wy,wz,t, got 3");
  EXPECT_EQ(line, 2);
  EXPECT_EQ(errorOf("1,2,3,4,\n", gyro),
            "file.txt:1: expected 4 comma-separated fields "
            "wx,wy,wz,t, got 5");
  EXPECT_EQ(errorOf("1,2x,3,4\n", gyro), "file.txt:1: wy (rad/s) '2x' is not a number");
  EXPECT_EQ(errorOf("1,2,3,\n", gyro), "file.txt:1: t (s) is empty");
  EXPECT_EQ(errorOf("1,nan,3,4\n", gyro), "file.txt:1: wy (rad/s) 'nan' is not a finite number");
  EXPECT_EQ(errorOf("1,2,3,5\n1,2,3,4\n", gyro),
            "file.txt:2: stamp 4.000000 s does not increase (previous 5.000000 s on line 1)");
  EXPECT_EQ(errorOf("", gyro), "file.txt: no gyro samples");
  EXPECT_EQ(errorOf("1.0\nabc\n", stamps), "file.txt:2: frame stamp (s) 'abc' is not a number");
  EXPECT_EQ(errorOf("1.0\n\n2.0\n", stamps),
            "file.txt:2: blank line inside the frame stamp list (only allowed at the end, since "
            "line i is frame i)");
  EXPECT_EQ(errorOf("2.0\n2.0\n", stamps),
            "file.txt:2: stamp 2.000000 s does not increase (previous 2.000000 s on line 1)");
  EXPECT_THROW(loadGyroCsv("/nonexistent/gyro.txt"), RecordingFormatError);
}

}  // namespace
}  // namespace deep_ois
