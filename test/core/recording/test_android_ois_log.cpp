// The deep-stabilization log reader (core/recording/android_ois_log.h) on the real Pixel 4 log
// (../shared/data/pixel4_dvs_ois; skipped when absent) and on bad input.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "deep_ois/core/recording/android_ois_log.h"

namespace deep_ois {
namespace {

TEST(AndroidOisLog, ReadsThePixel4LogSortedWithoutRepeats) {
  const std::string folder = std::string(DEEP_OIS_SOURCE_DIR) + "/../shared/data/pixel4_dvs_ois";
  if (!std::filesystem::exists(folder + "/calib.txt")) GTEST_SKIP() << "not found: " << folder;
  const AndroidOisLog log = readAndroidOisLog(folder);
  EXPECT_EQ(log.rates.size(), 2024u);
  EXPECT_EQ(log.lens_rows, 2564u);
  EXPECT_EQ(log.lens_out_of_order, 295u);  // the README's count of backward stamps
  EXPECT_EQ(log.lens.size() + log.lens_repeats_dropped, log.lens_rows);
  EXPECT_GT(log.lens_repeats_dropped, 400u);
  EXPECT_NEAR(log.focal_px, 4032.0 / 1.27, 1e-6);
  double largest_gap = 0.0;
  for (std::size_t k = 1; k < log.lens.size(); ++k) {
    ASSERT_GT(log.lens[k].stamp_s, log.lens[k - 1].stamp_s);
    largest_gap = std::max(largest_gap, log.lens[k].stamp_s - log.lens[k - 1].stamp_s);
  }
  EXPECT_LT(largest_gap, 0.021);  // the README: the largest real gap is 19.9 ms
  // Scaled to a 1008 px wide image: a quarter of the active-array pixels.
  AndroidOisLogOptions quarter;
  quarter.image_width_px = 1008.0;
  const AndroidOisLog scaled = readAndroidOisLog(folder, quarter);
  EXPECT_NEAR(scaled.lens[10].shift_px.x(), 0.25 * log.lens[10].shift_px.x(), 1e-9);
}

TEST(AndroidOisLog, NamesTheFileAndLineOfBadInput) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "deep_ois_android_log_test";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "calib.txt") << "{ \"fov\" : 1.27 }\n";
  std::ofstream(dir / "gyro_log_1.txt") << "1000 0.1 0.2 0.3 1007 1\n2000 0.1 oops 0.3 2007 1\n";
  std::ofstream(dir / "ois_log_1.txt") << "1 2.0 3.0 1000000\n";
  try {
    readAndroidOisLog(dir.string());
    FAIL() << "a bad gyro row was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("gyro_log_1.txt:2"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace deep_ois
