// compensation_malformed_gyro_flow.test (issue 31, item 11): the gyro flow nodelet's flows are
// relayed to the compensation nodelet through the test node, which breaks them one malformed kind
// at a time (each field of GyroFlow.msg). Checked, independently of the nodelets' own validation:
// no field of any output (compensated_flow, compensated_flow/image, compensation_check) is ever
// non-finite; each kind is refused in a throttled warning naming the topic and the field; good
// flows after the bad ones are compensated again at the input's rate. Then (item 3): stamps
// decades from ROS time are said once by each nodelet, naming use_sim_time.
#include <deep_ois/CompensationPairCheck.h>

#include <cmath>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "live_pipeline_rostest_helpers.h"

namespace deep_ois {
namespace {

using live_test::LivePipelineHarness;

LivePipelineHarness* harness = nullptr;
constexpr char kRelayTopic[] = "/deep_ois/gyro_flow_under_test";
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

template <typename Values>
bool allFinite(const Values& values) {
  for (const auto& v : values)
    if (!std::isfinite(v)) return false;
  return true;
}

// Every float field of a published GyroFlow, listed here rather than taken from the nodelets'
// validation, so that a field the validation forgets still fails this test.
std::string nonFiniteField(const GyroFlow& m) {
  if (!allFinite(m.homographies)) return "homographies";
  if (!allFinite(m.K)) return "K";
  if (!allFinite(m.D)) return "D";
  if (!std::isfinite(m.readout_time)) return "readout_time";
  if (!std::isfinite(m.time_offset)) return "time_offset";
  if (!std::isfinite(m.patch_time_fraction)) return "patch_time_fraction";
  if (!allFinite(m.imu_to_camera_rotation)) return "imu_to_camera_rotation";
  if (!allFinite(m.angular_velocity_times)) return "angular_velocity_times";
  if (!allFinite(m.angular_velocity)) return "angular_velocity";
  if (m.homographies.size() != 9 * static_cast<std::size_t>(m.patch_count) || m.patch_count == 0) {
    return "homographies (size)";
  }
  if (m.flow.width == 0 || m.flow.height == 0 || !live_test::flowIsFinite(m.flow)) return "flow";
  return {};
}

// Relays the gyro flows to the compensation, through the current break.
class Relay {
 public:
  Relay() {
    ros::NodeHandle nh;
    pub_ = nh.advertise<GyroFlow>(kRelayTopic, 100);
    sub_ = nh.subscribe<GyroFlow>(live_test::kGyroFlowTopic, 100, [this](const GyroFlowConstPtr& m) {
      auto copy = boost::make_shared<GyroFlow>(*m);
      std::lock_guard<std::mutex> lock(mutex_);
      if (edit_) edit_(*copy);
      pub_.publish(copy);
    });
    compensated_sub_ = nh.subscribe<GyroFlow>(live_test::kCompensatedTopic, 1000, [this](const GyroFlowConstPtr& m) {
      const std::string field = nonFiniteField(*m);
      std::lock_guard<std::mutex> lock(mutex_);
      ++compensated_;
      if (!field.empty()) bad_outputs_.push_back("compensated_flow " + field + " (" + case_ + ")");
    });
    image_sub_ = nh.subscribe<sensor_msgs::Image>(
        "/deep_ois/compensated_flow/image", 1000, [this](const sensor_msgs::ImageConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          if (m->width == 0 || !live_test::flowIsFinite(*m)) {
            bad_outputs_.push_back("compensated_flow/image (" + case_ + ")");
          }
        });
    check_sub_ = nh.subscribe<CompensationPairCheck>(
        "/deep_ois/compensation_check", 1000, [this](const CompensationPairCheckConstPtr& m) {
          // NaN residuals are the message's "no verdict" when not usable; nothing else may be.
          const bool finite = std::isfinite(m->confidence) &&
                              (!m->usable || (std::isfinite(m->model_residual) && std::isfinite(m->gyro_residual)));
          std::lock_guard<std::mutex> lock(mutex_);
          if (!finite) bad_outputs_.push_back("compensation_check (" + case_ + ")");
        });
  }
  bool connected() const { return pub_.getNumSubscribers() > 0; }
  void set(const std::string& name, std::function<void(GyroFlow&)> edit) {
    std::lock_guard<std::mutex> lock(mutex_);
    case_ = name;
    edit_ = std::move(edit);
  }
  std::vector<std::string> badOutputs() {
    std::lock_guard<std::mutex> lock(mutex_);
    return bad_outputs_;
  }

 private:
  ros::Publisher pub_;
  ros::Subscriber sub_, compensated_sub_, image_sub_, check_sub_;
  std::mutex mutex_;
  std::function<void(GyroFlow&)> edit_;
  std::string case_ = "good flows";
  std::size_t compensated_ = 0;
  std::vector<std::string> bad_outputs_;
};

struct Malformed {
  std::string name;
  std::function<void(GyroFlow&)> edit;
  std::string named;  // what the warning must name besides the topic
};

void setFlowValue(GyroFlow& m, std::size_t index, float value) {
  std::memcpy(&m.flow.data[4 * index], &value, sizeof value);
}

TEST(CompensationMalformedGyroFlow, NoNonFiniteOutputAndTheOutputRecovers) {
  Relay relay;
  harness->publishTf();
  ASSERT_TRUE(harness->waitForPipeline());
  const ros::WallTime connect_deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (!relay.connected() && ros::WallTime::now() < connect_deadline) ros::WallDuration(0.05).sleep();
  ASSERT_TRUE(relay.connected()) << "the compensation did not subscribe " << kRelayTopic;
  harness->stream(2.0);

  const std::vector<Malformed> cases = {
      {"NaN homography", [](GyroFlow& m) { m.homographies[4] = kNaN; }, "homographies[4]"},
      {"inf homography (lens log)",
       [](GyroFlow& m) {
         m.homographies[0] = kInf;
         m.motion_model = GyroFlow::MOTION_GYRO_LENS_LOG;  // published as measured: passed through
       },
       "homographies[0]"},
      {"NaN homography (lens log)",
       [](GyroFlow& m) {
         m.homographies.back() = kNaN;
         m.motion_model = GyroFlow::MOTION_GYRO_LENS_LOG;
       },
       "homographies["},
      {"homographies one short", [](GyroFlow& m) { m.homographies.pop_back(); }, "patch_count"},
      {"patch_count not the homographies'", [](GyroFlow& m) { m.patch_count += 1; }, "patch_count"},
      {"patch_count zero", [](GyroFlow& m) { m.patch_count = 0; }, "patch_count"},
      {"NaN K", [](GyroFlow& m) { m.K[2] = kNaN; }, "K[2]"},
      {"NaN D", [](GyroFlow& m) { m.D.assign(5, kNaN); }, "D[0]"},
      {"NaN readout_time", [](GyroFlow& m) { m.readout_time = kNaN; }, "readout_time"},
      {"inf time_offset", [](GyroFlow& m) { m.time_offset = kInf; }, "time_offset"},
      {"NaN patch_time_fraction", [](GyroFlow& m) { m.patch_time_fraction = kNaN; }, "patch_time_fraction"},
      {"NaN imu_to_camera_rotation", [](GyroFlow& m) { m.imu_to_camera_rotation[4] = kNaN; },
       "imu_to_camera_rotation[4]"},
      {"NaN angular_velocity", [](GyroFlow& m) { m.angular_velocity[1] = kNaN; }, "angular_velocity[1]"},
      {"NaN angular_velocity_times", [](GyroFlow& m) { m.angular_velocity_times[0] = kNaN; },
       "angular_velocity_times[0]"},
      {"angular_velocity one short", [](GyroFlow& m) { m.angular_velocity.pop_back(); }, "angular_velocity"},
      {"NaN flow", [](GyroFlow& m) { setFlowValue(m, 7, std::numeric_limits<float>::quiet_NaN()); }, "flow"},
      {"zero-size flow",
       [](GyroFlow& m) {
         m.flow.width = m.flow.height = m.flow.step = 0;
         m.flow.data.clear();
       },
       "flow"},
      {"flow data short", [](GyroFlow& m) { m.flow.data.resize(m.flow.data.size() / 2); }, "flow"},
      {"flow encoding", [](GyroFlow& m) { m.flow.encoding = "32FC1"; }, "flow encoding"},
      {"zero image size", [](GyroFlow& m) { m.image_width = 0; }, "image size"},
      {"previous_stamp after stamp", [](GyroFlow& m) { std::swap(m.previous_stamp, m.header.stamp); },
       "previous_stamp"},
  };
  for (const Malformed& c : cases) {
    SCOPED_TRACE(c.name);
    const ros::WallTime t_bad = ros::WallTime::now();
    relay.set(c.name, c.edit);
    harness->stream(1.0);
    relay.set("good flows after " + c.name, {});
    const ros::WallTime t_good = ros::WallTime::now();
    harness->stream(2.0);
    // Output again: the second second of good flows at the input's rate (a loaded machine may
    // delay a few pairs).
    const ros::WallTime from = t_good + ros::WallDuration(1.0), to = t_good + ros::WallDuration(2.0);
    const std::size_t frames = harness->framesBetween(from, to);
    const std::size_t compensated = harness->countBetween(true, from, to);
    std::printf("%-34s 1-2 s after good flows: %zu frames, %zu compensated flows\n", c.name.c_str(), frames,
                compensated);
    EXPECT_GE(compensated + 5, frames) << c.name << ": compensated " << compensated << " for " << frames
                                       << " frames\n" << harness->warningsText(t_bad);
    const std::vector<live_test::LogLine> found = harness->warnings(t_bad, {"compensation", kRelayTopic, c.named});
    EXPECT_FALSE(found.empty()) << c.name << ": no warning naming " << kRelayTopic << " and '" << c.named
                                << "'; warnings:\n" << harness->warningsText(t_bad);
    EXPECT_LE(found.size(), 3u) << c.name << ": not throttled";
  }
  const std::vector<std::string> bad = relay.badOutputs();
  std::string listed;
  for (std::size_t k = 0; k < bad.size() && k < 20; ++k) listed += "  " + bad[k] + "\n";
  EXPECT_TRUE(bad.empty()) << bad.size() << " outputs with a non-finite field:\n" << listed;
  EXPECT_EQ(harness->nonFiniteOutputs(), 0u);
}

// Item 3: the inputs stamped ~20 years before ROS time (a bag's stamps read on the wall clock):
// each nodelet says it once, naming use_sim_time, not once per message.
TEST(CompensationMalformedGyroFlow, StampsFarFromTheClockAreSaidOnce) {
  Relay relay;  // the compensation's input
  harness->publishTf();
  ASSERT_TRUE(harness->waitForPipeline());
  harness->stream(1.0);
  const ros::WallTime t_shift = ros::WallTime::now();
  harness->shiftStamps(ros::Duration(-20.0 * 365.25 * 86400.0));
  harness->stream(4.0);
  // Each nodelet's lines start with its name and a colon (the relay topic holds "gyro_flow" too).
  for (const char* node : {"/deep_ois/gyro_flow:", "/deep_ois/compensation:"}) {
    const std::vector<live_test::LogLine> said = harness->warnings(t_shift, {node, "use_sim_time", "behind ROS time"});
    EXPECT_EQ(said.size(), 1u) << node << ": warnings:\n" << harness->warningsText(t_shift);
  }
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::live_test::runLivePipelineGtests(argc, argv, "test_compensation_malformed_gyro_flow",
                                                    deep_ois::harness);
}
