// rostest of the deep_ois/gyro_flow nodelet on a clean synthetic stream: every frame pair must
// give a GyroFlow whose homographies match the analytic camera motion (integrated independently
// here), whose metadata restates the configuration, and whose flow is those homographies applied.
#include <iostream>
#include <map>

#include "gyro_flow_rostest_helpers.h"

namespace deep_ois {
namespace {

using namespace rostest_helpers;

constexpr int kFrameCount = 45;        // 1.5 s of video
constexpr double kImuLeadS = 0.05;     // IMU messages go out this much (stamp time) before frames
constexpr double kPlaybackSpeed = 3.0;  // faster than real time, in stamp order

TEST(GyroFlowSynthetic, MatchesAnalyticRotationForEveryFramePair) {
  RollingShutterTiming timing;
  ASSERT_TRUE(readTiming(timing));
  int grid_width_px = 0, grid_height_px = 0;
  ASSERT_TRUE(readGridSize(grid_width_px, grid_height_px));

  const Eigen::Matrix3d R_cam_imu = syntheticImuToCamera();
  const Eigen::Matrix3d K = syntheticK();
  LinearRateMotion motion;
  // A small epoch: the nodelet works in absolute double seconds, whose resolution at wall-clock
  // epochs (~1.7e9 s, 0.24 us) alone gives ~7e-6 relative (3e-4 px) and would hide the 1e-6 check.
  motion.reference_stamp = ros::Time(1000, 0);

  // IMU from 0.1 s before the first frame to 0.1 s after the last, stamps exact in nanoseconds.
  std::vector<StreamEvent> events;
  std::vector<ros::Time> frame_stamps;
  for (int j = 0; j < kFrameCount; ++j) {
    frame_stamps.push_back(motion.reference_stamp + ros::Duration(0.1 + j * kFramePeriodS));
  }
  const double end_tau_s = motion.tau(frame_stamps.back()) + 0.1;
  appendImuEvents(motion, R_cam_imu, end_tau_s, kImuLeadS, events);
  appendFrameEvents(motion, frame_stamps, events);
  sortByPublishKey(events);

  // gyro_flow_camera_info_only.test: the nodelet subscribes camera_info alone, never the images.
  bool camera_info_only = false;
  ros::param::get("~camera_info_only", camera_info_only);
  GyroFlowHarness harness(/*subscribe_color=*/true);
  // gyro_flow_sim_time.test (issue 14, defect 9: a replay with use_sim_time once gave no flow,
  // "no IMU-to-camera transform"): ROS time is 0 until the stream drives /clock, so /tf_static is
  // latched, stamped 0, before the clock starts and before the nodelet's first lookup, and the
  // nodelet's tf buffer was created before any /clock, as in a replay that starts the pipeline
  // first.
  bool sim_time = false;
  ros::param::get("~sim_time", sim_time);
  if (sim_time) {
    ASSERT_TRUE(ros::Time::isSimTime()) << "the launch must set /use_sim_time";
    ASSERT_TRUE(ros::Time::now().isZero()) << "no /clock may have been published before the transform";
    harness.driveClock(motion.reference_stamp);
  }
  // gyro_flow_sim_time.test also publishes the mount only after this many frames, as a player
  // that opens its /tf_static connection after the data flows does (rosbag play started past
  // it): the frames before must wait for it rather than lose their pairs.
  int transform_after_frames = 0;
  ros::param::get("~transform_after_frames", transform_after_frames);
  if (transform_after_frames == 0) {
    harness.publishStaticTransform(R_cam_imu);
    ASSERT_TRUE(harness.waitForNodelet(30.0, /*expect_image_subscriber=*/!camera_info_only));
    harness.play(events, kPlaybackSpeed);
  } else {
    ASSERT_TRUE(harness.waitForNodelet(30.0, /*expect_image_subscriber=*/!camera_info_only));
    auto split = events.begin();
    for (int frames = 0; split != events.end() && frames < transform_after_frames; ++split) {
      if (split->image || split->info) ++frames;
    }
    harness.play(std::vector<StreamEvent>(events.begin(), split), kPlaybackSpeed);
    harness.publishStaticTransform(R_cam_imu);
    harness.play(std::vector<StreamEvent>(split, events.end()), kPlaybackSpeed);
  }
  if (camera_info_only) {
    EXPECT_EQ(harness.imageSubscribers(), 0u) << "the nodelet subscribed the images";
  }

  // Expected: one GyroFlow per frame after the first, stamped with the later frame.
  std::map<ros::Time, ros::Time> previous_of;
  for (int j = 1; j < kFrameCount; ++j) previous_of[frame_stamps[j]] = frame_stamps[j - 1];
  const ros::Time last_stamp = frame_stamps.back();
  const bool complete = harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == last_stamp;
      },
      5.0);
  EXPECT_TRUE(complete) << "no GyroFlow for the last frame " << last_stamp;

  const std::vector<GyroFlowConstPtr> flows = harness.flows();
  std::map<ros::Time, int> received_count;
  HomographyError worst;
  for (const GyroFlowConstPtr& msg : flows) {
    SCOPED_TRACE("GyroFlow stamped " + std::to_string(msg->header.stamp.toSec()));
    ++received_count[msg->header.stamp];
    const auto pair = previous_of.find(msg->header.stamp);
    ASSERT_NE(pair, previous_of.end()) << "no frame pair ends at this stamp";
    EXPECT_TRUE(metadataAndFlowMatch(*msg, pair->second, timing, K, R_cam_imu, grid_width_px, grid_height_px));
    const std::vector<Eigen::Matrix3d> expected =
        expectedHomographies(motion, timing, K, pair->second, msg->header.stamp);
    const std::vector<Eigen::Matrix3d> actual = homographiesOf(*msg);
    EXPECT_TRUE(homographiesMatch(expected, actual));
    for (std::size_t i = 0; i < expected.size() && i < actual.size(); ++i) {
      const HomographyError error = homographyError(expected[i], actual[i]);
      worst.relative = std::max(worst.relative, error.relative);
      worst.pixel_px = std::max(worst.pixel_px, error.pixel_px);
    }

    // The test must be able to tell the rolling-shutter timing apart: top and bottom patches
    // differ by more than the tolerance, and the same pair without readout or time offset too.
    const Eigen::Vector2d centre(0.5 * (kImageWidthPx - 1), 0.5 * (kImageHeightPx - 1));
    ASSERT_EQ(actual.size(), static_cast<std::size_t>(timing.patch_count));
    EXPECT_GT((applyHomography(actual.front(), centre) - applyHomography(actual.back(), centre)).norm(), 0.1);
    RollingShutterTiming global_shutter = timing;
    global_shutter.readout_time_s = 0.0;
    global_shutter.time_offset_s = 0.0;
    EXPECT_FALSE(homographiesMatch(expectedHomographies(motion, global_shutter, K, pair->second,
                                                        msg->header.stamp),
                                   actual));
    // Sign convention: the camera pans right (positive rate about camera +y), so the scene, and
    // the image centre with it, moves left.
    EXPECT_LT(applyHomography(actual[timing.patch_count / 2], centre).x() - centre.x(), -1.0);
  }
  for (const auto& [stamp, count] : received_count) {
    EXPECT_EQ(count, 1) << "GyroFlow " << stamp << " published " << count << " times";
  }
  // The first pair may be lost while the connections settle; every later one must be there.
  for (int j = 2; j < kFrameCount; ++j) {
    EXPECT_EQ(received_count.count(frame_stamps[j]), 1u) << "no GyroFlow for frame " << j << " ("
                                                         << frame_stamps[j] << ")";
  }
  EXPECT_GE(flows.size(), static_cast<std::size_t>(kFrameCount - 2));
  std::cout << "[ INFO     ] " << flows.size() << " GyroFlow for " << kFrameCount - 1
            << " frame pairs; worst homography error " << worst.relative << " relative, "
            << worst.pixel_px << " px\n";

  // gyro_flow/color: one rgb8 image on the grid per GyroFlow.
  const std::vector<sensor_msgs::ImageConstPtr> colors = harness.colors();
  EXPECT_GE(colors.size(), static_cast<std::size_t>(kFrameCount - 2));
  for (const sensor_msgs::ImageConstPtr& color : colors) {
    EXPECT_EQ(color->encoding, "rgb8");
    EXPECT_EQ(static_cast<int>(color->width), grid_width_px);
    EXPECT_EQ(static_cast<int>(color->height), grid_height_px);
    EXPECT_GE(color->data.size(), static_cast<std::size_t>(color->step) * color->height);
    EXPECT_EQ(previous_of.count(color->header.stamp), 1u) << "color image stamped " << color->header.stamp;
  }
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::rostest_helpers::runRostestGtests(argc, argv, "test_gyro_flow_synthetic");
}
