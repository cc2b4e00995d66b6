// Issue 23's regression: the default compensator (the learned stabiliser model) stopped after time
// went back, because it kept the state and gyro stream of the old timeline and ignored the older
// samples (2 s back: [0, 14, 30, 30] compensated flows a second; 10 s back: none for 9 s). Both
// live nodelets in one manager with the shipped default model (live_time_jumps.test), fed in real
// time; stamps jump back 2 s and then 10 s. After each jump and a warm-up second, at least 95 % of
// the gyro flows must be compensated, and the compensation must say once per jump that its model
// restarted.
#include <string>
#include <vector>

#include "live_pipeline_rostest_helpers.h"

namespace deep_ois {
namespace {

using live_test::LivePipelineHarness;

LivePipelineHarness* harness = nullptr;

TEST(LiveTimeJumps, TheStabiliserModelRestartsOnEveryJumpBackAndCompensatesAgain) {
  harness->publishTf();
  ASSERT_TRUE(harness->waitForPipeline());
  harness->stream(3.0);
  for (double back_s : {2.0, 10.0}) {
    SCOPED_TRACE("time back by " + std::to_string(back_s) + " s");
    const ros::WallTime t_jump = ros::WallTime::now();
    harness->shiftStamps(ros::Duration(-back_s));
    harness->stream(4.0);
    // Outputs arrive a little after their input: wait for the stragglers before counting.
    ros::WallDuration(0.3).sleep();
    const ros::WallTime from = t_jump + ros::WallDuration(1.0), to = t_jump + ros::WallDuration(4.0);
    const std::size_t gyro = harness->countBetween(false, from, to);
    const std::size_t compensated = harness->countBetween(true, from, to + ros::WallDuration(0.3));
    std::printf("[ measured ] %.0f s back: %zu gyro flows, %zu compensated in the 3 s after the warm-up second\n",
                back_s, gyro, compensated);
    EXPECT_GE(gyro, 60u) << "the gyro flow did not recover\n" << harness->warningsText(t_jump);
    EXPECT_GE(static_cast<double>(compensated), 0.95 * static_cast<double>(gyro))
        << harness->warningsText(t_jump);
    const std::vector<live_test::LogLine> said =
        harness->warnings(t_jump, {"compensation", "went back by", "restarts from a centred lens"});
    EXPECT_EQ(said.size(), 1u) << "the restart must be said once per jump; warnings:\n" << harness->warningsText(t_jump);
  }
  EXPECT_EQ(harness->nonFiniteOutputs(), 0u);
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::live_test::runLivePipelineGtests(argc, argv, "test_live_time_jumps", deep_ois::harness);
}
