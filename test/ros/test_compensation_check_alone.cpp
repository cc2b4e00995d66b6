// compensation_check_alone.test: only compensation_check is subscribed; the checks must arrive
// (issue 31, item 2: the topic had no connect callback, so nothing was subscribed for it).
#include <deep_ois/CompensationPairCheck.h>

#include <atomic>

#include "live_pipeline_rostest_helpers.h"

namespace deep_ois {
namespace {

live_test::LivePipelineHarness* harness = nullptr;

TEST(CompensationCheckAlone, ALoneSubscriberGetsTheChecks) {
  ros::NodeHandle nh;
  std::atomic<int> checks{0};
  ros::Subscriber check_sub = nh.subscribe<CompensationPairCheck>(
      "/deep_ois/compensation_check", 100, [&](const CompensationPairCheckConstPtr&) { ++checks; });
  harness->publishTf();
  // The nodelets subscribe their inputs only because of our compensation_check subscriber.
  ASSERT_TRUE(harness->waitForPipeline(20.0))
      << "a lone compensation_check subscriber did not make the nodelets subscribe their inputs";
  harness->stream(8.0);
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (checks == 0 && ros::WallTime::now() < deadline) {
    harness->stream(0.5);
  }
  EXPECT_GT(checks.load(), 0) << "no compensation_check message; warnings:\n"
                              << harness->warningsText(ros::WallTime(0, 1));
  std::printf("%d compensation_check messages with no other output subscribed\n", checks.load());
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::live_test::runLivePipelineGtests(argc, argv, "test_compensation_check_alone", deep_ois::harness,
                                                    /*subscribe_outputs=*/false);
}
