// The fused motion's prior sigma from the recent per-pair checks (fusion_prior_sigma.h): the
// default before the first usable check, the median of the last ones, the floor, and what it
// ignores.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "deep_ois/core/fusion/fusion_prior_sigma.h"

namespace deep_ois {
namespace {

CompensationCheck usableCheck(double model_residual_px) {
  CompensationCheck check;
  check.usable = true;
  check.model_residual_px = model_residual_px;
  return check;
}

TEST(FusionPriorSigma, InitialSigmaBeforeTheFirstUsableCheck) {
  FusionPriorSigma sigma;
  EXPECT_DOUBLE_EQ(sigma.sigmaPx(), 0.5);
  CompensationCheck unusable;
  unusable.model_residual_px = 0.3;  // not usable: says nothing
  sigma.add(unusable);
  sigma.add(usableCheck(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_EQ(sigma.checks(), 0u);
  EXPECT_DOUBLE_EQ(sigma.sigmaPx(), 0.5);
}

TEST(FusionPriorSigma, MedianOfTheLastTenChecks) {
  FusionPriorSigma sigma;
  // 20 checks of 1.0 .. 2.9 px: the last ten are 2.0 .. 2.9, whose (upper) median is 2.5.
  for (int i = 0; i < 20; ++i) sigma.add(usableCheck(1.0 + 0.1 * i));
  EXPECT_EQ(sigma.checks(), 10u);
  EXPECT_NEAR(sigma.sigmaPx(), 2.5, 1e-12);
  sigma.clear();
  EXPECT_DOUBLE_EQ(sigma.sigmaPx(), 0.5);
}

TEST(FusionPriorSigma, NeverBelowTheFloor) {
  FusionPriorSigma sigma;
  for (int i = 0; i < 5; ++i) sigma.add(usableCheck(0.03));
  EXPECT_DOUBLE_EQ(sigma.sigmaPx(), 0.1);
  FusionPriorSigmaOptions options;
  options.min_sigma_px = 0.02;
  FusionPriorSigma lower(options);
  lower.add(usableCheck(0.03));
  EXPECT_DOUBLE_EQ(lower.sigmaPx(), 0.03);
}

TEST(FusionPriorSigma, BadOptionsAreRefusedByName) {
  FusionPriorSigmaOptions options;
  options.recent_checks = 0;
  try {
    FusionPriorSigma sigma(options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("recent_checks"), std::string::npos) << e.what();
  }
  options = {};
  options.min_sigma_px = 0.0;
  EXPECT_THROW(FusionPriorSigma{options}, std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
