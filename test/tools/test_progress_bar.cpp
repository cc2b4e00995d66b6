#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "deep_ois/tools/support/progress_bar.h"

namespace deep_ois {
namespace {

TEST(ProgressBar, ShowsCountRateAndEta) {
  const ProgressBar bar(10, "pairs", nullptr);
  EXPECT_EQ(bar.line(5, 2.5), "[###############               ] 5/10 pairs, 2.0 pairs/s, ETA 2 s");
  EXPECT_EQ(bar.line(10, 5.0),
            "[##############################] 10/10 pairs, 2.0 pairs/s, ETA 0 s");
  EXPECT_EQ(bar.line(0, 0.0), "[                              ] 0/10 pairs, ? pairs/s, ETA ?");
}

// The first item reported right after the bar was made (a bar created when a job learns its
// total) gave "1447178.0 fit steps/s": no rate over a span that short.
TEST(ProgressBar, NoRateOverTheFirstInstants) {
  const ProgressBar bar(16, "fit steps", nullptr);
  EXPECT_EQ(bar.line(1, 1e-6),
            "[#                             ] 1/16 fit steps, ? fit steps/s, ETA ?");
}

// A redirected stderr (a file) gets no carriage-return redraws: whole lines, the first update and
// the last (and one every 10 s between).
TEST(ProgressBar, WritesWholeLinesIntoAFile) {
  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  {
    ProgressBar bar(3, "pairs", file);
    EXPECT_FALSE(bar.drawing());
    bar.update(1);
    bar.update(2);  // within 10 s of the first: not written
    bar.update(3);
    bar.update(3);  // the last line once
  }
  std::fflush(file);
  std::rewind(file);
  std::string text;
  for (int c = std::fgetc(file); c != EOF; c = std::fgetc(file)) text += static_cast<char>(c);
  std::fclose(file);
  EXPECT_EQ(text.find('\r'), std::string::npos) << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 2) << text;
  EXPECT_NE(text.find("1/3 pairs"), std::string::npos) << text;
  EXPECT_NE(text.find("3/3 pairs"), std::string::npos) << text;
  EXPECT_EQ(text.find("2/3 pairs"), std::string::npos) << text;
}

// setTotal keeps the bar's clock: the rate counts from the construction.
TEST(ProgressBar, SetTotalKeepsCounting) {
  ProgressBar bar(0, "fit steps", nullptr);
  bar.setTotal(4);
  EXPECT_EQ(bar.line(2, 1.0),
            "[###############               ] 2/4 fit steps, 2.0 fit steps/s, ETA 1 s");
}

}  // namespace
}  // namespace deep_ois
