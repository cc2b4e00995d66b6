// Every bad input of issue 14's first paragraph, in a row, through both live nodelets in one
// manager (fuzz_live_pipeline.test). After each: the manager alive (required in the launch), a
// throttled warning naming the topic and the problem, full output rate within 1 s of good input;
// at the end: no NaN or inf in any flow published.
#include <limits>
#include <string>
#include <vector>

#include "live_pipeline_rostest_helpers.h"

namespace deep_ois {
namespace {

using live_test::FrameEdit;
using live_test::LivePipelineHarness;

LivePipelineHarness* harness = nullptr;

struct Case {
  std::string name;
  double bad_s;
  std::function<void(FrameEdit&)> edit_frame;
  std::function<bool(sensor_msgs::Imu&)> edit_imu;
  std::vector<std::vector<std::string>> expected_warnings;  // each: all parts in one warning
  std::function<void()> before;                              // e.g. a time jump
};

// Good input for 2 s after `t_good`; the second second must be at the input's rate.
void expectRecovered(const std::string& name, const ros::WallTime& t_bad, const ros::WallTime& t_good) {
  harness->stream(2.0);
  const ros::WallTime from = t_good + ros::WallDuration(1.0), to = t_good + ros::WallDuration(2.0);
  const std::size_t frames = harness->framesBetween(from, to);
  const std::size_t gyro = harness->countBetween(false, from, to), compensated = harness->countBetween(true, from, to);
  std::printf("%-28s 1-2 s after good input: %zu frames, %zu gyro flows, %zu compensated flows\n", name.c_str(),
              frames, gyro, compensated);
  // Pairs: one fewer than frames; a loaded CI machine may delay a few.
  EXPECT_GE(gyro + 3, frames) << name << ": gyro flows " << gyro << " for " << frames << " frames\n"
                              << harness->warningsText(t_bad);
  EXPECT_GE(compensated + 5, frames) << name << ": compensated " << compensated << " for " << frames << " frames\n"
                                     << harness->warningsText(t_bad);
}

TEST(FuzzLivePipeline, EveryBadInputIsSaidAndTheOutputRecovers) {
  harness->publishTf();
  ASSERT_TRUE(harness->waitForPipeline());
  harness->stream(2.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"NaN gyro rates", 1.0, {},
       [nan](sensor_msgs::Imu& imu) {
         imu.angular_velocity.y = nan;
         return true;
       },
       {{"gyro_flow", live_test::kImuTopic}}, {}},
      {"reversed stamps", 1.0,
       [](FrameEdit& e) {
         // Every other frame stamped 0.1 s in the past: out of order.
         if (e.index % 2 == 0) {
           e.image->header.stamp -= ros::Duration(0.1);
           e.info->header.stamp = e.image->header.stamp;
         }
       },
       {}, {{"gyro_flow", live_test::kImageTopic, "out-of-order"}}, {}},
      {"unsupported encoding", 1.0, [](FrameEdit& e) { e.image->encoding = "no_such_encoding"; }, {},
       {{"gyro_flow", live_test::kImageTopic, "encoding 'no_such_encoding'"},
        {"compensation", live_test::kCompensationImageTopic, "encoding 'no_such_encoding'"}}, {}},
      {"encoding/data mismatch", 1.0, [](FrameEdit& e) { e.image->encoding = "16UC3"; }, {},
       {{"gyro_flow", live_test::kImageTopic, "16UC3"}}, {}},
      {"zero-size images", 1.0,
       [](FrameEdit& e) {
         e.image->width = e.image->height = e.image->step = 0;
         e.image->data.clear();
       },
       {}, {{"gyro_flow", live_test::kImageTopic, "zero size"}, {"compensation", "zero size"}}, {}},
      {"missing tf frame", 1.0, [](FrameEdit& e) { e.image->header.frame_id = "camera_not_in_tf"; }, {},
       {{"gyro_flow", "no IMU-to-camera transform", "camera_not_in_tf"}}, {}},
      // 10.5 s: a whole 5 s watchdog window without a synchronised frame.
      {"missing camera_info", 10.5, [](FrameEdit& e) { e.send_info = false; }, {},
       {{"gyro_flow", "no frames", live_test::kInfoTopic}}, {}},
      {"time jump backwards", 1.0, {}, {}, {{"gyro_flow", "jumped backwards"}},
       [] { harness->shiftStamps(ros::Duration(-10.0)); }},
      {"bag loop", 1.0, {}, {}, {{"gyro_flow", "jumped backwards"}}, [] { harness->shiftStamps(ros::Duration(-3.0)); }},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const ros::WallTime t_bad = ros::WallTime::now();
    if (c.before) c.before();
    harness->stream(c.bad_s, c.edit_frame, c.edit_imu);
    const ros::WallTime t_good = ros::WallTime::now();
    expectRecovered(c.name, t_bad, t_good);
    for (const std::vector<std::string>& parts : c.expected_warnings) {
      const std::vector<live_test::LogLine> found = harness->warnings(t_bad, parts);
      std::string wanted;
      for (const std::string& p : parts) wanted += "'" + p + "' ";
      EXPECT_FALSE(found.empty()) << c.name << ": no warning with " << wanted << "; warnings:\n"
                                  << harness->warningsText(t_bad);
      // Throttled: at most one per 2 s period (plus the edges) for the same problem.
      EXPECT_LE(found.size(), static_cast<std::size_t>((c.bad_s + 2.0) / 2.0) + 2) << c.name << ": " << wanted;
    }
  }
  EXPECT_EQ(harness->nonFiniteOutputs(), 0u) << "flows with NaN or inf were published";
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::live_test::runLivePipelineGtests(argc, argv, "test_fuzz_live_pipeline", deep_ois::harness);
}
