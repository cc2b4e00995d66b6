// The compensation nodelet's choice of method (issue 31 item 10): the compensator from ~model, the
// method per pair, and the fallback to the plain gyro.
#include <gtest/gtest.h>

#include "deep_ois/core/ois/compensation_method.h"

namespace deep_ois {
namespace {

TEST(CompensationMethod, TheCompensatorComesFromTheModelFile) {
  EXPECT_EQ(compensatorKindFor("models/stabiliser_generic.yaml"), CompensatorKind::kStabiliserModel);
  EXPECT_EQ(compensatorKindFor("/opt/models/deep_ois_fast.pt"), CompensatorKind::kNetwork);
}

TEST(CompensationMethod, AFlowWithTheLensLogIsPublishedAsMeasured) {
  for (CompensatorKind kind : {CompensatorKind::kNetwork, CompensatorKind::kStabiliserModel}) {
    EXPECT_EQ(compensationMethodFor(kind, true), CompensationMethod::kAsMeasured);
  }
  EXPECT_FALSE(methodUsesModel(CompensationMethod::kAsMeasured));
}

TEST(CompensationMethod, AGyroFlowGoesToTheCompensatorLoaded) {
  EXPECT_EQ(compensationMethodFor(CompensatorKind::kNetwork, false), CompensationMethod::kNetwork);
  EXPECT_EQ(compensationMethodFor(CompensatorKind::kStabiliserModel, false), CompensationMethod::kStabiliserModel);
  EXPECT_TRUE(methodUsesModel(CompensationMethod::kNetwork));
  EXPECT_TRUE(methodUsesModel(CompensationMethod::kStabiliserModel));
}

TEST(CompensationMethod, OnlyTheStabiliserModelFallsBackToThePlainGyro) {
  EXPECT_TRUE(publishesPlainGyro(CompensationMethod::kStabiliserModel, true));
  EXPECT_FALSE(publishesPlainGyro(CompensationMethod::kStabiliserModel, false));
  EXPECT_FALSE(publishesPlainGyro(CompensationMethod::kNetwork, true));
  EXPECT_FALSE(publishesPlainGyro(CompensationMethod::kAsMeasured, true));
}

}  // namespace
}  // namespace deep_ois
