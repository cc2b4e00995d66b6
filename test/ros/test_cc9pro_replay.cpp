// rostest: the cc9pro phone recording through the real replay path. The test converts the
// recording (writePhoneRecordingBag, as convert_recording does), plays the bag with
// `rosbag play --clock` and collects what the gyro flow nodelet publishes; the homographies must
// match the authors' own within the tolerance of the direct cross-check (test_cc9pro).
#include <deep_ois/GyroFlow.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <map>
#include <mutex>
#include <string>

#include "cc9pro_reference.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "npy_reader.h"

namespace deep_ois {
namespace {

TEST(Cc9proReplay, NodeletReproducesAuthorsHomographies) {
  const std::string dir = test::cc9proDir();
  for (const char* name : {"gyro.txt", "framestamp.txt", "frames/RE_frame-99.jpg", "gyro_homo_h33_source.npy"}) {
    if (!test::fileExists(dir + "/" + name)) {
      GTEST_SKIP() << "cc9pro recording not found: looked for " << dir << "/" << name
                   << " (set DEEP_OIS_SHARED_DATA to the folder holding cc9pro/)";
    }
  }
  PhoneRecordingFiles files = cc9proLayout(dir);
  files.camera_info = std::string(DEEP_OIS_SOURCE_DIR) + "/config/cameras/cc9pro.yaml";
  const std::string bag_path = ::testing::TempDir() + "/cc9pro_replay.bag";
  PhoneRecordingBagOptions options;
  options.compression = rosbag::compression::Uncompressed;
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files, bag_path, options);
  ASSERT_EQ(stats.frames, 52);

  std::mutex mutex;
  std::map<ros::Time, std::vector<Eigen::Matrix3d>> flows;  // by the later frame's stamp
  std::map<ros::Time, ros::Time> previous_of;
  std::string problem;
  ros::NodeHandle nh;
  ros::Subscriber sub = nh.subscribe<GyroFlow>("/deep_ois/gyro_flow", 200, [&](const GyroFlowConstPtr& msg) {
    std::vector<Eigen::Matrix3d> homographies;
    cv::Mat flow;
    const std::string why = readGyroFlowMsg(*msg, homographies, flow);
    std::lock_guard<std::mutex> lock(mutex);
    if (!why.empty() && problem.empty()) problem = why;
    flows[msg->header.stamp] = homographies;
    previous_of[msg->header.stamp] = msg->previous_stamp;
  });

  // The real player: it waits until the nodelet subscribes its inputs (it does so once its output
  // has our subscriber), publishes /clock and the bag's topics.
  const std::string play = "rosbag play --clock --quiet --wait-for-subscribers " + bag_path +
                           " --topics /imu/data /camera/image_raw /camera/camera_info /tf_static";
  ASSERT_EQ(std::system(play.c_str()), 0) << play;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::WallTime::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (flows.size() >= 51u) break;
    }
    ros::WallDuration(0.1).sleep();
  }

  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_TRUE(problem.empty()) << problem;
  ASSERT_EQ(flows.size(), 51u) << "one GyroFlow per frame pair of the 52 frames";
  const PhoneRecording recording = loadPhoneRecording(dir);
  const test::NpyArray reference = test::readNpyFloat64(dir + "/gyro_homo_h33_source.npy");
  test::CornerDifference difference;
  for (int n = test::kAuthorsFirstPair; n <= test::kCc9proLastFrame; ++n) {
    const auto stamp = [&](int frame) {
      const long long us = std::llround(recording.frame_stamps_s.at(frame) * 1e6);
      return ros::Time(static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000) * 1000u);
    };
    const auto found = flows.find(stamp(n));
    ASSERT_NE(found, flows.end()) << "no GyroFlow for frame " << n;
    EXPECT_EQ(previous_of[stamp(n)], stamp(n - 1)) << "frame " << n;
    ASSERT_EQ(found->second.size(), 10u);
    for (int patch = 0; patch < 10; ++patch) {
      difference.add(found->second[patch], test::authorsHomography(reference, n, patch));
    }
  }
  const double mean_px = difference.meanPx(), max_px = difference.max_px;
  const int count = difference.count;
  std::cout << std::fixed << std::setprecision(6)
            << "[cc9pro replay] nodelet vs authors' homographies: corner difference mean " << mean_px
            << " px, max " << max_px << " px over " << count << " corners (51 pairs x 10 patches x 4)\n";
  EXPECT_LT(mean_px, 0.01);  // the tolerances of test_cc9pro
  EXPECT_LT(max_px, 0.05);
  std::remove(bag_path.c_str());
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cc9pro_replay");
  ros::NodeHandle nh;
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
