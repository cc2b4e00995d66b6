// rostest of the deep_ois/fundamental_mixtures nodelet (fundamental_mixtures_nodelet.test): the
// nodelet runs the offline job on a recording inside a nodelet manager; this node waits for its
// latched ~summary and checks the training bag against the input bag: one record per consecutive
// frame pair in order, accepted records with N target homographies and sensible inlier counts,
// rejected ones with a reason, and targets that align the input's annotated points.
#include <deep_ois/FramePairTruth.h>
#include <deep_ois/TrainingPair.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <numeric>
#include <string>
#include <vector>

#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
namespace {

constexpr char kImageTopic[] = "/camera/image_raw";
constexpr char kInfoTopic[] = "/camera/camera_info";
constexpr char kTruthTopic[] = "/ground_truth/frame_pair";
constexpr char kRecordTopic[] = "/deep_ois/training_pair";  // the job's default output topic
constexpr unsigned kPatchCount = 6;                         // config/gyro_flow.yaml
constexpr unsigned kMinInliers = 16;                        // FundamentalMixturesOptions default

template <typename Message>
std::vector<Message> readTopic(const std::string& path, const std::string& topic) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::vector<Message> messages;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic))) {
    const auto message = m.instantiate<Message>();
    if (message) messages.push_back(*message);
  }
  return messages;
}

TEST(FundamentalMixturesNodelet, WritesOneCheckedRecordPerFramePair) {
  ros::NodeHandle nh, private_nh("~");
  std::string summary_topic, input, output;
  double wait_s = 0.0;
  ASSERT_TRUE(private_nh.getParam("summary_topic", summary_topic));
  ASSERT_TRUE(private_nh.getParam("input", input));
  ASSERT_TRUE(private_nh.getParam("output", output));
  ASSERT_TRUE(private_nh.getParam("wait_s", wait_s));

  std::mutex mutex;
  std::string summary;
  const ros::Subscriber subscriber =
      nh.subscribe<std_msgs::String>(summary_topic, 1, [&](const std_msgs::String::ConstPtr& msg) {
        std::lock_guard<std::mutex> lock(mutex);
        summary = msg->data;
      });
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(wait_s);
  bool done = false;
  while (ros::ok() && !done && ros::WallTime::now() < deadline) {
    ros::WallDuration(0.1).sleep();
    std::lock_guard<std::mutex> lock(mutex);
    done = !summary.empty();
  }
  ASSERT_TRUE(done) << "no summary on " << summary_topic << " within " << wait_s << " s";
  std::printf("[ summary  ] %s\n", summary.c_str());
  ASSERT_EQ(summary.rfind("wrote " + output, 0), 0u) << summary;
  EXPECT_EQ(summary.find("bag error"), std::string::npos) << summary;

  const auto images = readTopic<sensor_msgs::Image>(input, kImageTopic);
  const auto infos = readTopic<sensor_msgs::CameraInfo>(input, kInfoTopic);
  const auto truths = readTopic<FramePairTruth>(input, kTruthTopic);
  const auto records = readTopic<TrainingPair>(output, kRecordTopic);
  ASSERT_GE(images.size(), 10u);
  ASSERT_FALSE(infos.empty());
  ASSERT_EQ(records.size(), images.size() - 1) << "one record per consecutive frame pair";
  std::map<ros::Time, const FramePairTruth*> truth_at;
  for (const FramePairTruth& truth : truths) truth_at[truth.header.stamp] = &truth;

  const std::size_t values = 9 * kPatchCount;
  std::size_t accepted = 0;
  double target_px = 0.0, identity_px = 0.0;
  int scored = 0;
  for (std::size_t k = 0; k < records.size(); ++k) {
    const TrainingPair& record = records[k];
    SCOPED_TRACE("record " + std::to_string(k));
    EXPECT_EQ(record.previous_stamp, images[k].header.stamp);
    EXPECT_EQ(record.header.stamp, images[k + 1].header.stamp);
    EXPECT_EQ(record.source_bag, input);
    EXPECT_EQ(record.image_width, infos[0].width);
    EXPECT_EQ(record.image_height, infos[0].height);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(record.K[i], infos[0].K[i]);
    ASSERT_EQ(record.patch_count, kPatchCount);
    // The simulator's IMU covers every pair of the recording.
    EXPECT_EQ(record.gyro_homographies.size(), values) << record.rejection_reason;
    EXPECT_LE(record.inlier_count, record.match_count);
    if (!record.accepted) {
      EXPECT_FALSE(record.rejection_reason.empty());
      EXPECT_EQ(record.model, "none");
      EXPECT_TRUE(record.target_homographies.empty());
      continue;
    }
    ++accepted;
    EXPECT_TRUE(record.rejection_reason.empty()) << record.rejection_reason;
    EXPECT_TRUE(record.model == "fundamental_mixtures" || record.model == "rotation_only_fallback")
        << record.model;
    ASSERT_EQ(record.target_homographies.size(), values);
    ASSERT_EQ(record.patch_inlier_counts.size(), kPatchCount);
    EXPECT_EQ(
        std::accumulate(record.patch_inlier_counts.begin(), record.patch_inlier_counts.end(), 0u),
        record.inlier_count);
    EXPECT_GE(record.inlier_count, kMinInliers);
    // A textured frame gives tracks everywhere: no patch of an accepted pair is empty, and the
    // robust stage keeps most tracks (bad KLT tracks are a few percent).
    for (unsigned count : record.patch_inlier_counts) EXPECT_GT(count, 0u);
    EXPECT_GE(record.inlier_count * 10, record.match_count * 7);
    EXPECT_TRUE(std::isfinite(record.residual_px));
    EXPECT_LT(record.residual_px, 1.0) << "median rotation-only residual, px";
    for (double value : record.target_homographies) ASSERT_TRUE(std::isfinite(value));

    const auto truth = truth_at.find(record.header.stamp);
    if (truth == truth_at.end()) continue;
    const auto points_a = unflattenPoints(truth->second->points_a);
    const auto points_b = unflattenPoints(truth->second->points_b);
    if (points_a.empty()) continue;
    const int h = static_cast<int>(record.image_height);
    target_px +=
        geometryDistance(points_a, points_b, unflattenMatrices(record.target_homographies), h);
    identity_px += geometryDistance(points_a, points_b, {Eigen::Matrix3d::Identity()}, h);
    ++scored;
  }
  std::printf(
      "[ measured ] %zu of %zu pairs accepted; annotated points: target %.3f px, identity "
      "%.3f px (mean over %d pairs)\n",
      accepted, records.size(), target_px / scored, identity_px / scored, scored);
  EXPECT_GE(accepted * 4, records.size() * 3) << "a textured RE scene gives most pairs a target";
  ASSERT_GT(scored, 0);
  EXPECT_LT(target_px, 0.7 * identity_px) << "the targets must align the frames";
  std::remove(output.c_str());
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_fundamental_mixtures_nodelet");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
