// readBagStaticTransforms (what the bag_static_transforms tool publishes for a replay): the sample
// bag's mount, several recorded static publishers merged, transforms tf would refuse, and bags
// without the topic, with another type on it, missing, or cut short.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/bag/bag_static_transforms.h"
#include "deep_ois/ros/messages/recording_bag_messages.h"

namespace deep_ois {
namespace {

geometry_msgs::TransformStamped transform(const std::string& parent, const std::string& child, double stamp_s,
                                          double yaw_rad) {
  geometry_msgs::TransformStamped t;
  t.header.frame_id = parent;
  t.header.stamp = ros::Time(stamp_s);
  t.child_frame_id = child;
  const Eigen::Quaterniond q(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  t.transform.rotation.w = q.w();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  return t;
}

tf2_msgs::TFMessage message(std::initializer_list<geometry_msgs::TransformStamped> transforms) {
  tf2_msgs::TFMessage m;
  m.transforms = transforms;
  return m;
}

std::string tempBag(const std::string& name) { return ::testing::TempDir() + "/" + name + ".bag"; }

TEST(BagStaticTransforms, TheSampleBagsMountIsTheOneTheEvaluatorReads) {
  const std::string sample = std::string(DEEP_OIS_SOURCE_DIR) + "/bags/sample.bag";
  const BagStaticTransforms read = readBagStaticTransforms(sample);
  ASSERT_EQ(read.message.transforms.size(), 1u) << read.summary("/tf_static");
  EXPECT_EQ(read.messages_read, 1u);
  EXPECT_TRUE(read.recovery_note.empty());
  const BagSequence sequence = readBagSequence(sample, BagSequenceTopics{});
  ASSERT_TRUE(sequence.imu_to_camera_rotation.has_value());
  const auto& t = read.message.transforms[0];
  // The camera's pose in the IMU frame: the rotation takes camera coordinates to IMU ones.
  EXPECT_EQ(t.header.frame_id, sequence.imu_frame_id);
  EXPECT_EQ(t.child_frame_id, sequence.camera_frame_id);
  const auto& q = t.transform.rotation;
  const Eigen::Matrix3d R_cam_imu = Eigen::Quaterniond(q.w, q.x, q.y, q.z).toRotationMatrix().transpose();
  EXPECT_LT((R_cam_imu - *sequence.imu_to_camera_rotation).norm(), 1e-12);
}

// Two static publishers recorded (each latched message alone reaches a late subscriber through
// rosbag play, the second hiding the first), one of them unlatched, the mount re-published later
// with a new value, and a transform tf would refuse: one message, the newest per child frame.
TEST(BagStaticTransforms, EveryPublishersTransformsMergeTheNewestPerChildFrame) {
  const std::string path = tempBag("static_merge");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    writeLatched(bag, "/tf_static", ros::Time(10.0), message({transform("camera", "imu", 10.0, 0.1)}),
                 "/mount_publisher");
    // Unlatched, as a bag rewritten by a tool that drops connection headers has it.
    bag.write("/tf_static", ros::Time(10.1),
              message({transform("base_link", "camera", 10.1, 0.2), transform("", "lidar", 10.1, 0)}));
    writeLatched(bag, "/tf_static", ros::Time(12.0), message({transform("camera", "imu", 12.0, 0.3)}),
                 "/mount_publisher");
  }
  const BagStaticTransforms read = readBagStaticTransforms(path);
  EXPECT_EQ(read.messages_read, 3u);
  ASSERT_EQ(read.message.transforms.size(), 2u);
  EXPECT_EQ(read.message.transforms[0].child_frame_id, "imu");
  EXPECT_EQ(read.message.transforms[0].header.stamp, ros::Time(12.0)) << "the newer mount wins";
  EXPECT_EQ(read.message.transforms[1].child_frame_id, "camera");
  EXPECT_EQ(read.transforms_skipped, 1u);
  const std::string summary = read.summary("/tf_static");
  EXPECT_NE(summary.find("2 static transforms (camera -> imu, base_link -> camera) from 3 messages on /tf_static"),
            std::string::npos) << summary;
  EXPECT_NE(summary.find("empty frame id in '' -> 'lidar'"), std::string::npos) << summary;
}

TEST(BagStaticTransforms, ABagWithoutTheTopicGivesNothingAndSaysSo) {
  const std::string path = tempBag("static_none");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    sensor_msgs::Imu imu;
    imu.header.stamp = ros::Time(5.0);
    bag.write("/imu/data", ros::Time(5.0), imu);
  }
  const BagStaticTransforms read = readBagStaticTransforms(path);
  EXPECT_TRUE(read.message.transforms.empty());
  EXPECT_EQ(read.summary("/tf_static"), "0 static transforms from 0 messages on /tf_static");
}

TEST(BagStaticTransforms, AnotherTypeOnTheTopicOrAMissingFileIsAnErrorNamingIt) {
  const std::string path = tempBag("static_wrong_type");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    sensor_msgs::Imu imu;
    bag.write("/tf_static", ros::Time(5.0), imu);
  }
  try {
    readBagStaticTransforms(path);
    FAIL() << "an Imu on /tf_static was read as transforms";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": /tf_static carries sensor_msgs/Imu, not tf2_msgs/TFMessage"),
              std::string::npos) << e.what();
  }
  const std::string missing = tempBag("static_no_such_bag");
  try {
    readBagStaticTransforms(missing);
    FAIL() << "a missing bag was read";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ": cannot open the bag", 0), 0u) << e.what();
  }
}

// A recording cut short (no index: rosbag play refuses it) still gives the mount written at its
// start, with a note saying the bag was scanned.
TEST(BagStaticTransforms, ABagCutShortStillGivesItsMount) {
  const std::string whole = tempBag("static_whole");
  {
    rosbag::Bag bag(whole, rosbag::bagmode::Write);
    bag.setChunkThreshold(4096);
    writeLatched(bag, "/tf_static", ros::Time(10.0), message({transform("camera", "imu", 10.0, 0.1)}),
                 "/mount_publisher");
    for (int k = 0; k < 2000; ++k) {
      sensor_msgs::Imu imu;
      imu.header.stamp = ros::Time(10.0 + k * 0.005);
      bag.write("/imu/data", imu.header.stamp, imu);
    }
  }
  const std::string cut = tempBag("static_cut");
  {
    std::ifstream in(whole, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() * 6 / 10);
  }
  const BagStaticTransforms read = readBagStaticTransforms(cut);
  ASSERT_EQ(read.message.transforms.size(), 1u);
  EXPECT_EQ(read.message.transforms[0].child_frame_id, "imu");
  EXPECT_EQ(read.recovery_note.rfind(cut + ": the bag has no valid index", 0), 0u) << read.recovery_note;
}

}  // namespace
}  // namespace deep_ois
