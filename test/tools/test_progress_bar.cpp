#include <gtest/gtest.h>

#include "deep_ois/tools/support/progress_bar.h"

namespace deep_ois {
namespace {

TEST(ProgressBar, ShowsCountRateAndEta) {
  const ProgressBar bar(10, "pairs", nullptr);
  EXPECT_EQ(bar.line(5, 2.5), "[###############               ] 5/10 pairs, 2.0 pairs/s, ETA 2 s");
  EXPECT_EQ(bar.line(10, 5.0), "[##############################] 10/10 pairs, 2.0 pairs/s, ETA 0 s");
  EXPECT_EQ(bar.line(0, 0.0), "[                              ] 0/10 pairs, 0.0 pairs/s, ETA ?");
}

}  // namespace
}  // namespace deep_ois
