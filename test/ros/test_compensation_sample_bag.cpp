// rostest of launch/deep_ois.launch on bags/sample.bag: the test node plays the bag (after the
// nodelets listen) and checks that every frame pair after the first yields a compensated flow,
// an aligned image, a ghost image and a flow colour image, consistent with the frames, and that
// the aligned previous frame matches the current frame better than the unaligned one does.
#include <deep_ois/GyroFlow.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>


#include "deep_ois/FramePairTruth.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/ros/messages/conversions.h"
#include "documented_diagnostics.h"

#include <map>
#include <mutex>
#include <set>

namespace deep_ois {

// Every key of every status on /diagnostics since the test node started (main subscribes before
// the tests run), by status name: a key published only once (after 15 pairs, after a fit) counts.
struct DiagnosticsKeysSeen {
  std::mutex mutex;
  std::map<std::string, std::set<std::string>> keys;
  void add(const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : msg->status) {
      for (const auto& kv : status.values) keys[status.name].insert(kv.key);
    }
  }
};
DiagnosticsKeysSeen diagnostics_keys_seen;

namespace {

constexpr double kPlaybackSpeed = 1.0;

struct Collected {
  std::mutex mutex;
  std::map<ros::Time, GyroFlowConstPtr> flows, gyro_flows;
  std::map<ros::Time, sensor_msgs::ImageConstPtr> aligned, ghosts, colors;
  std::map<ros::Time, sensor_msgs::ImageConstPtr> gyro_flow_images, compensated_flow_images;  // 32FC2
  std::map<ros::Time, int> duplicates;
};

template <typename Ptr>
void store(Collected& collected, std::map<ros::Time, Ptr>& into, const Ptr& msg) {
  std::lock_guard<std::mutex> lock(collected.mutex);
  if (!into.emplace(msg->header.stamp, msg).second) ++collected.duplicates[msg->header.stamp];
}

TEST(CompensationSampleBag, EveryPairAfterTheFirstIsAlignedAndCompensated) {
  ros::NodeHandle nh, private_nh("~");
  std::string bag_path;
  ASSERT_TRUE(private_nh.getParam("bag", bag_path));
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag);

  Collected collected;
  ros::Subscriber flow_sub = nh.subscribe<GyroFlow>(
      "/deep_ois/compensated_flow", 200, [&](const GyroFlowConstPtr& m) { store(collected, collected.flows, m); });
  ros::Subscriber gyro_sub = nh.subscribe<GyroFlow>(
      "/deep_ois/gyro_flow", 200, [&](const GyroFlowConstPtr& m) { store(collected, collected.gyro_flows, m); });
  ros::Subscriber aligned_sub = nh.subscribe<sensor_msgs::Image>(
      "/deep_ois/aligned/image_raw", 200, [&](const sensor_msgs::ImageConstPtr& m) { store(collected, collected.aligned, m); });
  ros::Subscriber ghost_sub = nh.subscribe<sensor_msgs::Image>(
      "/deep_ois/aligned/ghost", 200, [&](const sensor_msgs::ImageConstPtr& m) { store(collected, collected.ghosts, m); });
  ros::Subscriber color_sub = nh.subscribe<sensor_msgs::Image>(
      "/deep_ois/compensated_flow/color", 200,
      [&](const sensor_msgs::ImageConstPtr& m) { store(collected, collected.colors, m); });
  ros::Subscriber gyro_image_sub = nh.subscribe<sensor_msgs::Image>(
      "/deep_ois/gyro_flow/image", 200,
      [&](const sensor_msgs::ImageConstPtr& m) { store(collected, collected.gyro_flow_images, m); });
  ros::Subscriber compensated_image_sub = nh.subscribe<sensor_msgs::Image>(
      "/deep_ois/compensated_flow/image", 200,
      [&](const sensor_msgs::ImageConstPtr& m) { store(collected, collected.compensated_flow_images, m); });

  // One publisher per topic of the bag, with queues that hold the whole 2 s recording.
  std::map<std::string, ros::Publisher> publishers;
  std::map<ros::Time, sensor_msgs::ImageConstPtr> frames;
  std::map<ros::Time, FramePairTruthConstPtr> truths;  // by frame b's stamp
  for (const rosbag::ConnectionInfo* connection : view.getConnections()) {
    if (publishers.count(connection->topic)) continue;
    ros::AdvertiseOptions options(connection->topic, 5000, connection->md5sum, connection->datatype,
                                  connection->msg_def);
    options.latch = connection->topic == "/tf_static";
    publishers[connection->topic] = nh.advertise(options);
  }
  // Wait until the pipeline listens to its inputs (it subscribes lazily, once our subscribers
  // connect) and publishes to us.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  auto ready = [&] {
    return publishers["/imu/data"].getNumSubscribers() > 0 && publishers["/camera/image_raw"].getNumSubscribers() > 0 &&
           publishers["/camera/camera_info"].getNumSubscribers() > 0 && publishers["/tf_static"].getNumSubscribers() > 0 &&
           flow_sub.getNumPublishers() > 0 && aligned_sub.getNumPublishers() > 0 && ghost_sub.getNumPublishers() > 0 &&
           color_sub.getNumPublishers() > 0 && gyro_image_sub.getNumPublishers() > 0 &&
           compensated_image_sub.getNumPublishers() > 0;
  };
  while (!ready() && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
  ASSERT_TRUE(ready()) << "the pipeline did not subscribe to the bag's topics within 60 s";
  // Both nodelets share the manager's one connection per topic, so the count above cannot show
  // the second subscription; it is registered right after the first one: give it a moment.
  ros::WallDuration(1.0).sleep();

  // Play in bag order at the recorded pace.
  const ros::WallTime start = ros::WallTime::now();
  const ros::Time first = view.getBeginTime();
  for (const rosbag::MessageInstance& m : view) {
    const ros::WallTime due = start + ros::WallDuration((m.getTime() - first).toSec() / kPlaybackSpeed);
    const ros::WallTime now = ros::WallTime::now();
    if (due > now) (due - now).sleep();
    publishers[m.getTopic()].publish(m);
    if (m.getTopic() == "/camera/image_raw") {
      const sensor_msgs::ImageConstPtr image = m.instantiate<sensor_msgs::Image>();
      frames[image->header.stamp] = image;
    } else if (const FramePairTruthConstPtr truth = m.instantiate<FramePairTruth>()) {
      truths[truth->header.stamp] = truth;
    }
  }
  ASSERT_GE(frames.size(), 30u);
  const ros::Time last = frames.rbegin()->first;
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::WallTime::now() < wait_until) {
    {
      std::lock_guard<std::mutex> lock(collected.mutex);
      if (collected.flows.count(last) && collected.aligned.count(last) && collected.ghosts.count(last) &&
          collected.colors.count(last) && collected.compensated_flow_images.count(last) &&
          collected.gyro_flow_images.count(last)) {
        break;
      }
    }
    ros::WallDuration(0.05).sleep();
  }

  std::lock_guard<std::mutex> lock(collected.mutex);
  EXPECT_TRUE(collected.duplicates.empty()) << collected.duplicates.size() << " stamps published twice";
  int pairs = 0, scored = 0;
  double gyro_sum_px = 0.0, compensated_sum_px = 0.0;
  // The first pair may be lost while the connections settle (as with rosbag play, the first frame
  // can race the latched /tf_static); every later one must be there.
  for (auto it = std::next(frames.begin(), 2); it != frames.end(); ++it) {
    const ros::Time stamp = it->first, previous = std::prev(it)->first;
    SCOPED_TRACE("frame " + std::to_string(stamp.toSec()));
    ASSERT_TRUE(collected.flows.count(stamp)) << "no compensated_flow";
    ASSERT_TRUE(collected.aligned.count(stamp)) << "no aligned/image_raw";
    ASSERT_TRUE(collected.ghosts.count(stamp)) << "no aligned/ghost";
    ASSERT_TRUE(collected.colors.count(stamp)) << "no compensated_flow/color";
    const GyroFlow& flow = *collected.flows[stamp];
    EXPECT_EQ(flow.previous_stamp, previous);
    EXPECT_EQ(flow.flow.encoding, "32FC2");
    const sensor_msgs::Image& aligned = *collected.aligned[stamp];
    const sensor_msgs::Image& frame = *it->second;
    EXPECT_EQ(aligned.width, frame.width);
    EXPECT_EQ(aligned.height, frame.height);
    EXPECT_EQ(aligned.encoding, frame.encoding);
    EXPECT_EQ(collected.ghosts[stamp]->encoding, "rgb8");
    // The plain 32FC2 image topics carry exactly the flows of the GyroFlow messages.
    ASSERT_TRUE(collected.compensated_flow_images.count(stamp)) << "no compensated_flow/image";
    ASSERT_TRUE(collected.gyro_flow_images.count(stamp)) << "no gyro_flow/image";
    for (const auto& [image, message] : {std::make_pair(collected.compensated_flow_images[stamp], collected.flows[stamp]),
                                         std::make_pair(collected.gyro_flow_images[stamp], collected.gyro_flows[stamp])}) {
      ASSERT_TRUE(message);
      EXPECT_EQ(image->encoding, "32FC2");
      EXPECT_EQ(image->width, message->flow.width);
      EXPECT_EQ(image->height, message->flow.height);
      EXPECT_EQ(image->header.frame_id, message->header.frame_id);
      EXPECT_TRUE(image->data == message->flow.data) << "the flow image differs from the message's flow";
    }
    // Geometry distance on the annotated points (the evaluator's metric), uncapped.
    const auto truth = truths.find(stamp);
    if (truth != truths.end() && collected.gyro_flows.count(stamp)) {
      const auto points_a = unflattenPoints(truth->second->points_a), points_b = unflattenPoints(truth->second->points_b);
      std::vector<Eigen::Matrix3d> homographies;
      cv::Mat gyro_grid, compensated_grid;
      ASSERT_EQ(readGyroFlowMsg(*collected.gyro_flows[stamp], homographies, gyro_grid), "");
      ASSERT_EQ(readGyroFlowMsg(flow, homographies, compensated_grid), "");
      const cv::Size camera(static_cast<int>(frame.width), static_cast<int>(frame.height));
      if (private_nh.param("expect_compensated_homographies", false)) {
        // A stabiliser model's message carries its per-patch motion, not the gyro's.
        EXPECT_NE(flow.homographies, collected.gyro_flows[stamp]->homographies);
      }
      gyro_sum_px += geometryDistanceOfGridFlow(points_a, points_b, gyro_grid, camera);
      compensated_sum_px += geometryDistanceOfGridFlow(points_a, points_b, compensated_grid, camera);
      ++scored;
    }
    ++pairs;
  }
  ASSERT_GE(scored, pairs - 2) << "annotated pairs without a gyro flow";
  std::printf("[ INFO     ] %d pairs; geometry distance on %d annotated pairs: gyro %.3f px, compensated %.3f px\n",
              pairs, scored, gyro_sum_px / scored, compensated_sum_px / scored);
  // The model must remove most of the uncompensated gyro flow's error on this OIS camera
  // (measured with the network: 1.057 -> 0.307 px; the first network, without the motion history,
  // reached 0.756): ~max_compensated_ratio of the gyro's error at most.
  double max_ratio = 0.5;
  private_nh.param("max_compensated_ratio", max_ratio, max_ratio);
  EXPECT_LT(compensated_sum_px, max_ratio * gyro_sum_px);
}

// Runs after the test above: both nodelets report on /diagnostics what they did with the bag and
// which model and calibration they use.
TEST(CompensationSampleBag, DiagnosticsReportTheModelAndTheFlows) {
  ros::NodeHandle nh;
  std::mutex mutex;
  std::map<std::string, std::map<std::string, std::string>> latest;  // status name -> key -> value
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& status : msg->status) {
          for (const auto& kv : status.values) latest[status.name][kv.key] = kv.value;
        }
      });
  const std::string compensation = "deep_ois/compensation: status", gyro = "deep_ois/gyro_flow: status";
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::WallTime::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (latest.count(compensation) && latest.count(gyro)) break;
    }
    ros::WallDuration(0.1).sleep();
  }
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_TRUE(latest.count(compensation)) << "no status '" << compensation << "' on /diagnostics";
  ASSERT_TRUE(latest.count(gyro)) << "no status '" << gyro << "' on /diagnostics";
  std::map<std::string, std::string>& values = latest[compensation];
  for (const auto& [key, value] : values) std::printf("[ INFO     ]   %s: %s\n", key.c_str(), value.c_str());
  const std::string model = values["model"];
  ros::NodeHandle private_nh("~");
  std::string shipped = "models/fast.pt";
  private_nh.param("model_suffix", shipped, shipped);
  EXPECT_EQ(model.substr(model.size() - std::min(model.size(), shipped.size())), shipped);
  if (shipped.size() > 3 && shipped.substr(shipped.size() - 3) == ".pt") {
    EXPECT_EQ(values["torch threads"], "1");
  } else {
    EXPECT_EQ(values["model kind"], "learned stabiliser model");
  }
  // A model without a camera record cannot be checked against the stream, and must not say "matches".
  ASSERT_TRUE(values.count("model camera check")) << "no camera check on /diagnostics";
  if (values["model camera"] == "none recorded (a generic model)") {
    EXPECT_EQ(values["model camera check"], "not checked (the model records no camera)");
  } else {
    EXPECT_NE(values["model camera check"], "not checked (the model records no camera)");
  }
  EXPECT_GE(std::stoi(values["compensated flows total"]), 28);
  if (private_nh.param("expect_fusion", false)) {
    // ~fusion: the share refined, the mean correction and the last prior kept are said; the bag
    // is textured, so the tracks refine some of its pairs.
    for (const char* key : {"fusion: pairs refined [%]", "fusion: mean correction [px]", "fusion: last prior kept",
                            "fusion: failures (model's motion published)"}) {
      EXPECT_TRUE(values.count(key)) << "no '" << key << "' on /diagnostics";
    }
    EXPECT_GT(std::stod(values["fusion: pairs refined [%]"]), 0.0);
    EXPECT_EQ(values["fusion: failures (model's motion published)"], "0");
  }
  EXPECT_GE(std::stoi(latest[gyro]["gyro flows total"]), 28);
  EXPECT_GT(std::stoi(latest[gyro]["imu total"]), 100);
}

// Runs after the two above (the whole bag was compensated): the keys both nodelets published over
// the run against the tables of docs/ros_api.md (as test_parameter_docs does for the parameters).
TEST(CompensationSampleBag, DiagnosticsKeysAreDocumented) {
  ros::NodeHandle private_nh("~");
  std::string model = "models/fast.pt";
  private_nh.param("model_suffix", model, model);
  const bool network = model.size() > 3 && model.substr(model.size() - 3) == ".pt";
  const std::string model_kind = network ? "network" : "stabiliser model";
  const std::string docs = std::string(DEEP_OIS_SOURCE_DIR) + "/docs/ros_api.md";
  // One more period, so that what the last pairs set is in a status too.
  ros::WallDuration(1.5).sleep();
  std::lock_guard<std::mutex> lock(diagnostics_keys_seen.mutex);
  for (const std::string nodelet : {"deep_ois/gyro_flow", "deep_ois/compensation"}) {
    SCOPED_TRACE(nodelet);
    const std::vector<DocumentedDiagnosticsKey> documented = documentedDiagnosticsKeys(docs, nodelet);
    ASSERT_FALSE(documented.empty()) << "no table '### " << nodelet << " keys' under '## Diagnostics' in " << docs;
    const std::set<std::string>& published = diagnostics_keys_seen.keys[nodelet + ": status"];
    ASSERT_FALSE(published.empty()) << "no status '" << nodelet << ": status' on /diagnostics";
    std::printf("[ INFO     ] %s published %zu keys with the %s; docs/ros_api.md lists %zu\n", nodelet.c_str(),
                published.size(), model_kind.c_str(), documented.size());
    for (const std::string& problem : diagnosticsKeyProblems(documented, published, nodelet, model_kind)) {
      ADD_FAILURE() << problem;
    }
  }
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_compensation_sample_bag");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::NodeHandle nh;
  deep_ois::DiagnosticsKeysSeen& seen = deep_ois::diagnostics_keys_seen;
  const ros::Subscriber diagnostics_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&seen](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) { seen.add(msg); });
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
