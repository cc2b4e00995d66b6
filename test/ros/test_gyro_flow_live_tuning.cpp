// rostest of the gyro flow nodelet's live tuning and health: time_offset changed through
// dynamic_reconfigure in the middle of a synthetic stream changes the very next GyroFlow (and the
// pair across the change is still published: the IMU buffer and frame history are kept); then
// /diagnostics reports the rates, the calibration in use, and a dropped pair with its reason; and
// the parameter loader refuses a parameter of the wrong type, naming it.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/client.h>

#include <deep_ois/GyroFlowConfig.h>

#include <map>

#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "gyro_flow_rostest_helpers.h"

namespace deep_ois {
namespace {

using namespace rostest_helpers;

constexpr int kFrameCount = 30;
constexpr int kFramesBeforeChange = 15;
constexpr double kNewTimeOffsetS = 0.012;
constexpr double kImuLeadS = 0.05;
constexpr double kPlaybackSpeed = 3.0;

// One harness for both tests: its subscription keeps the nodelet's inputs (and state) alive between
// them, as a viewer that stays connected would.
GyroFlowHarness& sharedHarness() {
  static GyroFlowHarness harness(/*subscribe_color=*/false);
  return harness;
}

// IMU (from 0.1 s before the first frame to 0.1 s after the last) and frames of `motion`.
std::vector<StreamEvent> makeStream(const LinearRateMotion& motion, const Eigen::Matrix3d& R_cam_imu,
                                    const std::vector<ros::Time>& frame_stamps) {
  std::vector<StreamEvent> events;
  const double begin_tau_s = motion.tau(frame_stamps.front()) - 0.1;
  const double end_tau_s = motion.tau(frame_stamps.back()) + 0.1;
  for (int k = 0;; ++k) {
    const ros::Time stamp = frame_stamps.front() - ros::Duration(0.1) + ros::Duration(0, 2500000) * k;
    if (motion.tau(stamp) > end_tau_s) break;
    if (motion.tau(stamp) < begin_tau_s) continue;
    StreamEvent event;
    event.publish_key_s = motion.tau(stamp) - kImuLeadS;
    event.imu = makeImu(stamp, kImuFrame, R_cam_imu.transpose() * motion.cameraRate(motion.tau(stamp)));
    events.push_back(event);
  }
  appendFrameEvents(motion, frame_stamps, events);
  sortByPublishKey(events);
  return events;
}

TEST(GyroFlowLiveTuning, TimeOffsetChangedMidStreamAppliesToTheNextFrame) {
  RollingShutterTiming before;
  ASSERT_TRUE(readTiming(before));
  ASSERT_NE(before.time_offset_s, kNewTimeOffsetS);
  RollingShutterTiming after = before;
  after.time_offset_s = kNewTimeOffsetS;

  const Eigen::Matrix3d R_cam_imu = syntheticImuToCamera();
  const Eigen::Matrix3d K = syntheticK();
  LinearRateMotion motion;
  motion.reference_stamp = ros::Time(1000, 0);
  std::vector<ros::Time> frame_stamps;
  for (int j = 0; j < kFrameCount; ++j) {
    frame_stamps.push_back(motion.reference_stamp + ros::Duration(0.1 + j * kFramePeriodS));
  }
  const std::vector<StreamEvent> events = makeStream(motion, R_cam_imu, frame_stamps);
  // Everything published before frame kFramesBeforeChange, then the rest.
  const double split_key_s = motion.tau(frame_stamps[kFramesBeforeChange]) - 1e-6;
  std::vector<StreamEvent> first, second;
  for (const StreamEvent& event : events) (event.publish_key_s < split_key_s ? first : second).push_back(event);

  GyroFlowHarness& harness = sharedHarness();
  harness.publishStaticTransform(R_cam_imu);
  ASSERT_TRUE(harness.waitForNodelet(30.0));
  harness.play(first, kPlaybackSpeed);
  const ros::Time last_before = frame_stamps[kFramesBeforeChange - 1];
  ASSERT_TRUE(harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == last_before;
      },
      10.0))
      << "no GyroFlow for frame " << last_before << " before the change";

  dynamic_reconfigure::Client<GyroFlowConfig> client(kNodeletNamespace);
  GyroFlowConfig config;
  ASSERT_TRUE(client.getCurrentConfiguration(config, ros::Duration(10.0)))
      << "no dynamic_reconfigure server at " << kNodeletNamespace;
  EXPECT_DOUBLE_EQ(config.time_offset, before.time_offset_s) << "the server does not start from ~time_offset";
  config.time_offset = kNewTimeOffsetS;
  ASSERT_TRUE(client.setConfiguration(config));
  EXPECT_DOUBLE_EQ(config.time_offset, kNewTimeOffsetS);

  harness.play(second, kPlaybackSpeed);
  ASSERT_TRUE(harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == frame_stamps.back();
      },
      10.0))
      << "no GyroFlow for the last frame";

  const std::vector<GyroFlowConstPtr> flows = harness.flows();
  // One flow per pair, including the pair across the change: nothing was reset.
  ASSERT_EQ(flows.size(), static_cast<std::size_t>(kFrameCount - 1));
  for (std::size_t n = 0; n < flows.size(); ++n) {
    const GyroFlow& msg = *flows[n];
    const ros::Time stamp_a = frame_stamps[n], stamp_b = frame_stamps[n + 1];
    ASSERT_EQ(msg.header.stamp, stamp_b);
    ASSERT_EQ(msg.previous_stamp, stamp_a);
    const bool changed = static_cast<int>(n + 1) >= kFramesBeforeChange;
    const RollingShutterTiming& timing = changed ? after : before;
    const RollingShutterTiming& other = changed ? before : after;
    SCOPED_TRACE("GyroFlow " + std::to_string(stamp_b.toSec()) + (changed ? " after" : " before") + " the change");
    EXPECT_DOUBLE_EQ(msg.time_offset, timing.time_offset_s);
    const std::vector<Eigen::Matrix3d> actual = homographiesOf(msg);
    EXPECT_TRUE(homographiesMatch(expectedHomographies(motion, timing, K, stamp_a, stamp_b), actual));
    // The change is visible: the other offset does not explain this flow.
    EXPECT_FALSE(homographiesMatch(expectedHomographies(motion, other, K, stamp_a, stamp_b), actual));
    if (static_cast<int>(n + 1) == kFramesBeforeChange) {
      const HomographyError shift = homographyError(expectedHomographies(motion, before, K, stamp_a, stamp_b)[0],
                                                    expectedHomographies(motion, after, K, stamp_a, stamp_b)[0]);
      std::cout << "first pair after the change: the 8 ms offset change moves patch 0's corners by "
                << shift.pixel_px << " px" << std::endl;
    }
  }
}

// Runs after the test above (gtest keeps the order of one file): the nodelet has seen its stream.
TEST(GyroFlowLiveTuning, DiagnosticsReportRatesDropsAndCalibration) {
  ros::NodeHandle nh;
  std::mutex mutex;
  std::vector<diagnostic_msgs::DiagnosticStatus> statuses;
  // diagnostic_updater drops the leading slash of the node name.
  const std::string name = std::string(kNodeletNamespace).substr(1) + ": status";
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& status : msg->status) {
          if (status.name == name) statuses.push_back(status);
        }
      });

  // A second stream one second after the first: its first frame cannot pair with the first
  // stream's last one (> ~max_frame_interval), a drop the diagnostics must name.
  const Eigen::Matrix3d R_cam_imu = syntheticImuToCamera();
  LinearRateMotion motion;
  motion.reference_stamp = ros::Time(1000, 0);
  std::vector<ros::Time> frame_stamps;
  for (int j = 0; j < 10; ++j) {
    frame_stamps.push_back(motion.reference_stamp + ros::Duration(0.1 + (kFrameCount + 30 + j) * kFramePeriodS));
  }
  GyroFlowHarness& harness = sharedHarness();
  ASSERT_TRUE(harness.waitForNodelet(30.0));
  harness.play(makeStream(motion, R_cam_imu, frame_stamps), kPlaybackSpeed);
  ASSERT_TRUE(harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == frame_stamps.back();
      },
      10.0));

  // The totals are cumulative: wait for a status that has counted every flow.
  const std::size_t expected_flows = (kFrameCount - 1) + (frame_stamps.size() - 1);
  std::map<std::string, std::string> values;
  double max_imu_rate_hz = 0.0;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::WallTime::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& status : statuses) {
        for (const auto& kv : status.values) {
          if (kv.key == "imu rate [Hz]") max_imu_rate_hz = std::max(max_imu_rate_hz, std::stod(kv.value));
        }
      }
      if (!statuses.empty()) {
        values.clear();
        for (const auto& kv : statuses.back().values) values[kv.key] = kv.value;
        if (values["gyro flows total"] == std::to_string(expected_flows)) break;
      }
    }
    ros::WallDuration(0.1).sleep();
  }
  ASSERT_FALSE(values.empty()) << "no status named '" << name << "' on /diagnostics";
  for (const auto& [key, value] : values) std::cout << "  " << key << ": " << value << "\n";
  EXPECT_EQ(values["gyro flows total"], std::to_string(expected_flows));
  EXPECT_EQ(values["frames total"], std::to_string(kFrameCount + frame_stamps.size()));
  EXPECT_EQ(values["dropped: frames further apart than ~max_frame_interval"], "1");
  EXPECT_EQ(values["dropped total"], "1");
  EXPECT_DOUBLE_EQ(std::stod(values["time_offset [s]"]), kNewTimeOffsetS);
  EXPECT_EQ(values["R_cam_imu source"], std::string("tf ") + kImuFrame + " -> " + kCameraFrame);
  EXPECT_GT(max_imu_rate_hz, 100.0) << "the IMU plays at 400 Hz x " << kPlaybackSpeed;
  EXPECT_NE(values.find("latency mean [s]"), values.end());
}

// One loader, strict types: a parameter set with the wrong type is an error naming it (it used to
// fall back to the default without a word), and an integer where a double belongs is accepted.
TEST(GyroFlowParameters, WrongTypeIsAnErrorNamingTheParameter) {
  const std::string ns = "/strict_parameters_test";
  ros::param::set(ns + "/readout_time", std::string("fast"));
  try {
    loadGyroFlowParameters(ros::NodeHandle(ns));
    ADD_FAILURE() << "a string readout_time was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(ns + "/readout_time: has the wrong type: expected a number"),
              std::string::npos)
        << e.what();
  }
  ros::param::set(ns + "/readout_time", 0);  // an integer where a double belongs
  ros::param::set(ns + "/use_camera_info_only", 1.5);
  try {
    loadGyroFlowParameters(ros::NodeHandle(ns));
    ADD_FAILURE() << "a number use_camera_info_only was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(ns + "/use_camera_info_only: has the wrong type: expected true or false"),
              std::string::npos)
        << e.what();
  }
  ros::param::set(ns + "/use_camera_info_only", true);
  const GyroFlowParameters loaded = loadGyroFlowParameters(ros::NodeHandle(ns));
  EXPECT_EQ(loaded.rolling_shutter.readout_time_s, 0.0);
  EXPECT_TRUE(loaded.use_camera_info_only);
  ros::param::del(ns);
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::rostest_helpers::runRostestGtests(argc, argv, "test_gyro_flow_live_tuning");
}
