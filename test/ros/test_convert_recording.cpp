#include <deep_ois/LensShiftSample.h>
// The phone recording converter (convert_recording): a tiny hand-made recording written to a temp
// folder, its malformed variants, and the real cc9pro recording when ../shared is present.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cc9pro_reference.h"
#include "run_command.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "npy_reader.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

// Exact ROS time of a stamp given in whole microseconds (how both recordings store their stamps).
ros::Time fromMicroseconds(long long us) {
  return ros::Time(static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000) * 1000u);
}

// A tiny recording: 200 Hz gyro over 1 s, 10 frame stamps at ~30 fps, images of frames 3..6
// (8x6 pixels, pixel (0, 0) pure red), a README that must be ignored, and a calibration file.
class TinyRecording : public ::testing::Test {
 protected:
  static constexpr long long kStartUs = 4328040000000LL;  // a boot clock, as on the phone
  static constexpr int kWidth = 8;
  static constexpr int kHeight = 6;

  void SetUp() override {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = ::testing::TempDir() + "/convert_recording_" + info->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_ + "/frames");
    {
      std::ofstream gyro(dir_ + "/gyro.txt");
      for (int k = 0; k < 200; ++k) {
        gyro << std::setprecision(18) << 0.001 * k << "," << -0.002 * k << "," << 0.5 << ","
             << (kStartUs + 5000LL * k) * 1e-6 << "\n";
      }
    }
    {
      std::ofstream stamps(dir_ + "/framestamp.txt");
      for (int i = 0; i < 10; ++i) stamps << std::setprecision(18) << frameStampUs(i) * 1e-6 << "\n";
    }
    for (int i = 3; i <= 6; ++i) writeImage(dir_ + "/frames/frame-" + std::to_string(i) + ".png", false);
    std::ofstream(dir_ + "/frames/README.txt") << "not an image\n";
    writeCalibration(kWidth, kHeight);
    files_ = cc9proLayout(dir_);
    files_.camera_info = dir_ + "/camera.yaml";
    options_ = PhoneRecordingBagOptions{};
    options_.compression = rosbag::compression::Uncompressed;
    bag_path_ = dir_ + "/out.bag";
  }

  // Frame i at 200 ms + i * 33.313 ms after the start: microsecond stamps, like the phone's.
  static long long frameStampUs(int i) { return kStartUs + 200000LL + 33313LL * i; }

  void writeImage(const std::string& path, bool gray, int width = kWidth, int height = kHeight) {
    cv::Mat image(height, width, gray ? CV_8UC1 : CV_8UC3, cv::Scalar::all(40));
    if (gray) image.at<uint8_t>(0, 0) = 200;
    else image.at<cv::Vec3b>(0, 0) = cv::Vec3b(0, 0, 255);  // OpenCV writes BGR: this is red
    ASSERT_TRUE(cv::imwrite(path, image));
  }

  void writeCalibration(int width, int height) {
    std::ofstream yaml(dir_ + "/camera.yaml");
    yaml << "image_width: " << width << "\nimage_height: " << height
         << "\ncamera_name: tiny\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
            "  data: [10.5, 0, 3.5, 0, 11, 2.5, 0, 0, 1]\ndistortion_model: plumb_bob\n"
            "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.01, 0, 0, 0, 0]\n"
            "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
            "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [10.5, 0, 3.5, 0, 0, 11, 2.5, 0, 0, 0, 1, 0]\n";
  }

  // The message of the error the conversion throws ("" when it succeeds).
  std::string conversionError() {
    try {
      writePhoneRecordingBag(files_, bag_path_, options_);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  }

  std::string dir_;
  PhoneRecordingFiles files_;
  PhoneRecordingBagOptions options_;
  std::string bag_path_;
};

// Issue 31 #7: --recording's help describes every layout the converter accepts (it described the
// cc9pro folder alone).
TEST(ConvertRecordingHelp, RecordingDescribesEveryLayout) {
  std::string help;
  ASSERT_EQ(test::runCommand(std::string(DEEP_OIS_CONVERT_RECORDING_EXE) + " --help", help), 0);
  const std::size_t at = help.find("--recording");
  ASSERT_NE(at, std::string::npos) << help;
  const std::string recording = help.substr(at, help.find("\n  --", at + 1) - at);
  for (const char* part : {"gyro.txt", "framestamp.txt", "frames/", "lens_shift.txt", "video_meta.pb3", ".mp4",
                           "frame_timestamps_", "gyro_log_", "ois_log_", "calib.txt"})
    EXPECT_NE(recording.find(part), std::string::npos) << part << " not in: " << recording;
}

TEST_F(TinyRecording, WritesTheTopicsOfARobotRecording) {
  int progress_calls = 0;
  const PhoneRecordingBagStats stats =
      writePhoneRecordingBag(files_, bag_path_, options_, [&](int done, int total) {
        ++progress_calls;
        EXPECT_EQ(total, 4);
        EXPECT_EQ(done, progress_calls);
      });
  EXPECT_EQ(stats.frames, 4);
  EXPECT_EQ(stats.first_frame_index, 3);
  EXPECT_EQ(stats.last_frame_index, 6);
  EXPECT_EQ(stats.skipped_frame_indices, 0);
  EXPECT_EQ(stats.encoding, "rgb8");
  EXPECT_EQ(progress_calls, 4);
  // Gyro kept within 0.5 s of frames 3..6 (stamps 299.94 ms .. 399.88 ms after the start): the
  // 200 rows lie at 0, 5, .. 995 ms, the window is [-200.06, 899.88] ms -> rows 0..179.
  EXPECT_EQ(stats.imu_messages, 180);

  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  std::vector<sensor_msgs::Image> images;
  std::vector<sensor_msgs::CameraInfo> infos;
  std::vector<sensor_msgs::Imu> imu;
  ros::Time previous;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    EXPECT_GE(m.getTime(), previous) << "messages must be in time order";
    previous = m.getTime();
    if (auto image = m.instantiate<sensor_msgs::Image>()) {
      EXPECT_EQ(m.getTopic(), "/camera/image_raw");
      EXPECT_EQ(m.getTime(), image->header.stamp);
      images.push_back(*image);
    } else if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
      EXPECT_EQ(m.getTopic(), "/camera/camera_info");
      infos.push_back(*info);
    } else if (auto sample = m.instantiate<sensor_msgs::Imu>()) {
      EXPECT_EQ(m.getTopic(), "/imu/data");
      EXPECT_EQ(m.getTime(), sample->header.stamp);
      imu.push_back(*sample);
    } else {
      EXPECT_EQ(m.getTopic(), "/tf_static");
      EXPECT_EQ(m.getConnectionHeader()->at("latching"), "1");
    }
  }
  ASSERT_EQ(images.size(), 4u);
  ASSERT_EQ(infos.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    // Stamp = the recorded start-of-frame time, to the nanosecond.
    EXPECT_EQ(images[k].header.stamp, fromMicroseconds(frameStampUs(3 + k))) << "frame " << 3 + k;
    EXPECT_EQ(infos[k].header, images[k].header);
    EXPECT_EQ(images[k].header.frame_id, "camera_optical_frame");
    EXPECT_EQ(images[k].encoding, "rgb8");
    ASSERT_EQ(images[k].width, 8u);
    ASSERT_EQ(images[k].height, 6u);
    EXPECT_EQ(images[k].data[0], 255);  // red first: BGR was turned into RGB
    EXPECT_EQ(images[k].data[1], 0);
    EXPECT_EQ(images[k].data[2], 0);
  }
  EXPECT_EQ(infos[0].distortion_model, "plumb_bob");
  EXPECT_DOUBLE_EQ(infos[0].K[0], 10.5);
  EXPECT_DOUBLE_EQ(infos[0].K[4], 11.0);
  EXPECT_DOUBLE_EQ(infos[0].D[0], 0.01);
  ASSERT_EQ(imu.size(), 180u);
  EXPECT_EQ(imu[7].header.stamp, fromMicroseconds(kStartUs + 5000LL * 7));
  EXPECT_EQ(imu[7].header.frame_id, "imu_link");
  EXPECT_DOUBLE_EQ(imu[7].angular_velocity.x, 0.007);
  EXPECT_DOUBLE_EQ(imu[7].angular_velocity.y, -0.014);
  EXPECT_DOUBLE_EQ(imu[7].angular_velocity.z, 0.5);
  EXPECT_EQ(imu[7].orientation_covariance[0], -1.0);
  EXPECT_EQ(imu[7].linear_acceleration_covariance[0], -1.0);
  EXPECT_EQ(imu[7].angular_velocity_covariance[0], 0.0);  // unknown
  bag.close();

  // Read back the way the nodelets' offline twins read a robot's bag: tf gives R_cam_imu.
  const BagSequence sequence = readBagSequence(bag_path_);
  ASSERT_TRUE(sequence.imu_to_camera_rotation.has_value());
  EXPECT_LT((*sequence.imu_to_camera_rotation - cc9proImuToCameraRotation()).norm(), 1e-12);
  EXPECT_EQ(sequence.frame_stamps.size(), 4u);
  EXPECT_EQ(sequence.imu_samples.size(), 180u);
}

// A lens-shift CSV beside the gyro (lens_shift.txt of the layout): header, comment, rows with and
// without covariance; written as deep_ois/LensShiftSample on the frames' clock plus the clock
// offset, within the gyro's window around the frames; a malformed row names file and line.
TEST_F(TinyRecording, LensShiftCsvBecomesTheLensShiftTopic) {
  {
    std::ofstream lens(dir_ + "/lens_shift.txt");
    lens << "t_s,x,y\n# OisSample rows\n";
    for (int k = 0; k < 250; ++k) {
      lens << std::setprecision(18) << (kStartUs + 4000LL * k) * 1e-6 << "," << 0.25 * k << "," << -0.5 * k;
      if (k % 2 == 1) lens << ",0.01,0.002,0.03";
      lens << "\n";
    }
  }
  files_ = cc9proLayout(dir_);
  files_.camera_info = dir_ + "/camera.yaml";
  ASSERT_EQ(files_.lens_shift_csv, dir_ + "/lens_shift.txt");
  options_.clock_offset_s = 10.0;
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files_, bag_path_, options_);
  // Window [-200.06, 899.88] ms after the start: rows at 0, 4, .. 896 ms -> 225 rows.
  EXPECT_EQ(stats.lens_shift_messages, 225);
  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  int k = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/camera/lens_shift"))) {
    const auto sample = m.instantiate<LensShiftSample>();
    ASSERT_TRUE(sample);
    // Within the nanosecond: the CSV holds double seconds.
    EXPECT_LE(std::abs((sample->header.stamp - fromMicroseconds(kStartUs + 4000LL * k + 10000000LL)).toNSec()), 1);
    EXPECT_EQ(sample->header.frame_id, "camera_optical_frame");
    EXPECT_DOUBLE_EQ(sample->x, 0.25 * k);
    EXPECT_DOUBLE_EQ(sample->y, -0.5 * k);
    if (k % 2 == 1) {
      EXPECT_DOUBLE_EQ(sample->covariance[0], 0.01);
      EXPECT_DOUBLE_EQ(sample->covariance[1], 0.002);
      EXPECT_DOUBLE_EQ(sample->covariance[2], 0.002);
      EXPECT_DOUBLE_EQ(sample->covariance[3], 0.03);
    } else {
      EXPECT_EQ(sample->covariance[0], -1.0);
    }
    ++k;
  }
  EXPECT_EQ(k, 225);
  bag.close();

  std::ofstream(dir_ + "/lens_shift.txt") << "t,x,y\n1.0,2,3\n1.1,2\n";
  EXPECT_NE(conversionError().find("lens_shift.txt:3: expected 3 comma-separated fields"), std::string::npos)
      << conversionError();
  // Two lens positions at one instant: no order can be right.
  std::ofstream(dir_ + "/lens_shift.txt") << "4328040.3,2,3\n4328040.3,2,4\n";
  EXPECT_NE(conversionError().find("lens_shift.txt:2: stamp 4328040.300000000 s is also the stamp of line 1"),
            std::string::npos)
      << conversionError();
}

// Issue 23 #3: Android delivers OisSample[] per frame, each batch starting with a copy of the
// previous batch's last sample, its stamp off by microseconds (up to ~1 ms): the stamps step back in
// file order. Such a log converts, sorted, the copies dropped, counted and said.
TEST_F(TinyRecording, RepeatedOisSamplesOfAndroidBatchesAreSortedDroppedAndCounted) {
  {
    std::ofstream lens(dir_ + "/lens_shift.txt");
    lens << std::setprecision(18);
    int written = 0;
    for (int batch = 0; batch < 50; ++batch) {
      // Batch b holds samples 5b .. 5b+4 (5 ms apart); from batch 1 on it starts with a copy of the
      // previous batch's last sample, 20 us (or, every 10th batch, 900 us) earlier than the original.
      if (batch > 0) {
        const int k = 5 * batch - 1;
        const long long off_us = batch % 10 == 0 ? 900 : 20;
        lens << (kStartUs + 5000LL * k - off_us) * 1e-6 << "," << 0.25 * k << "," << -0.5 * k << "\n";
        ++written;
      }
      for (int k = 5 * batch; k < 5 * batch + 5; ++k) {
        lens << (kStartUs + 5000LL * k) * 1e-6 << "," << 0.25 * k << "," << -0.5 * k << "\n";
        ++written;
      }
    }
    ASSERT_EQ(written, 250 + 49);
  }
  files_ = cc9proLayout(dir_);
  files_.camera_info = dir_ + "/camera.yaml";
  options_.imu_margin_s = 10.0;  // every sample in the bag
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files_, bag_path_, options_);
  EXPECT_EQ(stats.lens_shift_repeats_dropped, 49);
  EXPECT_EQ(stats.lens_shift_steps_back, 49);
  EXPECT_EQ(stats.lens_shift_messages, 250);
  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  int k = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/camera/lens_shift"))) {
    const auto sample = m.instantiate<LensShiftSample>();
    ASSERT_TRUE(sample);
    // The original (first delivered) of each repeated sample is kept, at its own stamp.
    EXPECT_LE(std::abs((sample->header.stamp - fromMicroseconds(kStartUs + 5000LL * k)).toNSec()), 1) << k;
    EXPECT_DOUBLE_EQ(sample->x, 0.25 * k);
    ++k;
  }
  EXPECT_EQ(k, 250);
}

// Issue 23 #2: a recording of logs alone (no frames/ folder: the gyro, the frame stamps and the lens
// log, for train_stabiliser --target log) converts without placeholder images: camera_info per
// frame stamp, no image topic.
TEST_F(TinyRecording, RecordingWithoutFramesConvertsToCameraInfoAlone) {
  fs::remove_all(dir_ + "/frames");
  files_ = cc9proLayout(dir_);
  files_.camera_info = dir_ + "/camera.yaml";
  EXPECT_TRUE(files_.images_dir.empty());
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files_, bag_path_, options_);
  EXPECT_FALSE(stats.images);
  EXPECT_EQ(stats.frames, 10);
  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  EXPECT_EQ(rosbag::View(bag, rosbag::TopicQuery("/camera/image_raw")).size(), 0u);
  int k = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/camera/camera_info"))) {
    const auto info = m.instantiate<sensor_msgs::CameraInfo>();
    ASSERT_TRUE(info);
    EXPECT_LE(std::abs((info->header.stamp - fromMicroseconds(frameStampUs(k))).toNSec()), 1);
    EXPECT_EQ(info->width, static_cast<unsigned>(kWidth));
    ++k;
  }
  EXPECT_EQ(k, 10);
  bag.close();
  // What train_stabiliser --target log reads: the frame stamps from camera_info, without images.
  const BagSequence sequence = readBagSequence(bag_path_, {}, BagReadFailure::kThrow, nullptr);
  EXPECT_EQ(sequence.frame_stamps.size(), 10u);
  ASSERT_TRUE(sequence.camera);
}

// Frames and gyro stamped on two clocks (here: the gyro in Unix time, the frames on the boot clock)
// are said as such, naming both files, not as a gyro that starts late.
TEST_F(TinyRecording, StampsOnTwoClocksAreSaid) {
  {
    std::ofstream gyro(dir_ + "/gyro.txt");
    for (int k = 0; k < 200; ++k) gyro << std::setprecision(18) << "0,0,0.5," << 1.7e9 + 0.005 * k << "\n";
  }
  const std::string error = conversionError();
  EXPECT_NE(error.find("stamps on two clocks"), std::string::npos) << error;
  EXPECT_NE(error.find(dir_ + "/framestamp.txt"), std::string::npos) << error;
  EXPECT_NE(error.find(dir_ + "/gyro.txt"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(bag_path_));
}

// Issue 23 #1: the tool suggests --drop-uncovered-frames; the tool must take it.
TEST_F(TinyRecording, ToolTakesTheDropUncoveredFramesFlagItSuggests) {
  {
    std::ofstream gyro(dir_ + "/gyro.txt");
    for (int k = 0; k < 200; ++k) {
      gyro << std::setprecision(18) << 0.001 << "," << 0.0 << "," << 0.5 << ","
           << (kStartUs + 200000LL + 3 * 33313LL + 4000LL + 5000LL * k) * 1e-6 << "\n";
    }
  }
  const std::string command = std::string(DEEP_OIS_CONVERT_RECORDING_EXE) + " --quiet --recording " + dir_ +
                              " --camera-info " + dir_ + "/camera.yaml --out " + bag_path_;
  std::string output;
  EXPECT_NE(test::runCommand(command + " 2>&1", output), 0);
  EXPECT_NE(output.find("--drop-uncovered-frames leaves them out"), std::string::npos) << output;
  EXPECT_EQ(test::runCommand(command + " --drop-uncovered-frames 2>&1", output), 0) << output;
  EXPECT_NE(output.find("3 frames"), std::string::npos) << output;
  // Issue 31 #8: counts agree with their nouns, and every time says what it is a time of.
  EXPECT_NE(output.find("1 frame the gyro does not cover left out"), std::string::npos) << output;
  EXPECT_EQ(output.find(" 1 frames"), std::string::npos) << output;
  EXPECT_NE(output.find("frame stamps: first "), std::string::npos) << output;
  EXPECT_NE(output.find(" s of recording between them"), std::string::npos) << output;
  EXPECT_NE(output.find("converted in "), std::string::npos) << output;
  EXPECT_NE(output.find(" s (wall time"), std::string::npos) << output;
  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  EXPECT_EQ(rosbag::View(bag, rosbag::TopicQuery("/camera/image_raw")).size(), 3u);
}

// Issue 23 #2 through the tool: no frames/ folder converts (the summary says so).
TEST_F(TinyRecording, ToolConvertsARecordingWithoutFrames) {
  fs::remove_all(dir_ + "/frames");
  std::string output;
  EXPECT_EQ(test::runCommand(std::string(DEEP_OIS_CONVERT_RECORDING_EXE) + " --quiet --recording " + dir_ +
                                 " --camera-info " + dir_ + "/camera.yaml --out " + bag_path_ + " 2>&1",
                             output),
            0)
      << output;
  EXPECT_NE(output.find("10 frames without images (camera_info only)"), std::string::npos) << output;
}

TEST_F(TinyRecording, MonoImagesOffsetsTopicsAndFrames) {
  for (int i = 3; i <= 6; ++i) writeImage(dir_ + "/frames/frame-" + std::to_string(i) + ".png", true);
  fs::remove(dir_ + "/frames/frame-5.png");  // a dropped frame
  options_.image_topic = "/cam/image";
  options_.camera_info_topic = "/cam/info";
  options_.imu_topic = "/gyro";
  options_.camera_frame_id = "cam";
  options_.imu_frame_id = "gyro";
  options_.clock_offset_s = 1000.0;
  options_.frame_stamp_offset_s = -0.004;
  Eigen::Matrix3d rotation;
  rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized());
  options_.imu_to_camera_rotation = rotation;
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files_, bag_path_, options_);
  EXPECT_EQ(stats.frames, 3);
  EXPECT_EQ(stats.skipped_frame_indices, 1);
  EXPECT_EQ(stats.encoding, "mono8");
  EXPECT_EQ(stats.first_frame_stamp, fromMicroseconds(frameStampUs(3) + 1000000000LL - 4000));
  EXPECT_EQ(stats.last_frame_stamp, fromMicroseconds(frameStampUs(6) + 1000000000LL - 4000));

  BagSequenceTopics topics;
  topics.image = "/cam/image";
  topics.camera_info = "/cam/info";
  topics.imu = "/gyro";
  const BagSequence sequence = readBagSequence(bag_path_, topics);
  ASSERT_EQ(sequence.frame_stamps.size(), 3u);
  EXPECT_EQ(sequence.frame_stamps[2], fromMicroseconds(frameStampUs(6) + 1000000000LL - 4000));
  EXPECT_EQ(sequence.camera_frame_id, "cam");
  EXPECT_EQ(sequence.imu_frame_id, "gyro");
  ASSERT_TRUE(sequence.imu_to_camera_rotation.has_value());
  EXPECT_LT((*sequence.imu_to_camera_rotation - rotation).norm(), 1e-12);
  // The clock offset moves the gyro too: sample 0 is at the start + 1000 s.
  EXPECT_NEAR(sequence.imu_samples.front().stamp_s + sequence.time_base.toSec(),
              kStartUs * 1e-6 + 1000.0, 1e-6);

  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/cam/image"))) {
    const auto image = m.instantiate<sensor_msgs::Image>();
    ASSERT_TRUE(image);
    EXPECT_EQ(image->encoding, "mono8");
    EXPECT_EQ(image->data[0], 200);
  }
}

// A gyro log that starts a few ms after the first frame: refused by default, naming how many
// frames lie outside and the flag; with drop_uncovered_frames only those frames are left out,
// counted.
TEST_F(TinyRecording, GyroStartingAfterTheFirstFrameDropsOnlyTheUncoveredFrames) {
  {
    // Frame 3 is at 300 ms after the start; the gyro starts 4 ms later.
    std::ofstream gyro(dir_ + "/gyro.txt");
    for (int k = 0; k < 200; ++k) {
      gyro << std::setprecision(18) << 0.001 << "," << 0.0 << "," << 0.5 << ","
           << (kStartUs + 200000LL + 3 * 33313LL + 4000LL + 5000LL * k) * 1e-6 << "\n";
    }
  }
  std::string error = conversionError();
  EXPECT_NE(error.find(dir_ + "/gyro.txt: the gyro samples"), std::string::npos) << error;
  EXPECT_NE(error.find("1 of 4 frames lie outside; --drop-uncovered-frames leaves them out"), std::string::npos)
      << error;
  EXPECT_FALSE(fs::exists(bag_path_));

  options_.drop_uncovered_frames = true;
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files_, bag_path_, options_);
  EXPECT_EQ(stats.dropped_uncovered_frames, 1);
  EXPECT_EQ(stats.frames, 3);
  EXPECT_EQ(stats.first_frame_index, 4);
  rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
  EXPECT_EQ(rosbag::View(bag, rosbag::TopicQuery("/camera/image_raw")).size(), 3u);
}

// Image files numbered from 1 against a stamp list whose line 0 is frame 0: caught before anything
// is written, with the likely cause, not when the last image finds no stamp.
TEST_F(TinyRecording, FramesNumberedFromOneAgainstStampsFromZeroAreCaughtAtOnce) {
  fs::remove_all(dir_ + "/frames");
  fs::create_directories(dir_ + "/frames");
  for (int i = 1; i <= 10; ++i) writeImage(dir_ + "/frames/frame-" + std::to_string(i) + ".png", false);
  const std::string error = conversionError();
  EXPECT_EQ(error.rfind(dir_ + "/frames: the image files are numbered 1..10 but " + dir_ +
                            "/framestamp.txt has 10 lines, i.e. frames 0..9",
                        0),
            0u)
      << error;
  EXPECT_NE(error.find("the files look numbered from 1; renumber them from 0"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(bag_path_));
}

TEST_F(TinyRecording, MalformedInputsNameTheFileAndLine) {
  {
    std::ofstream gyro(dir_ + "/gyro.txt", std::ios::app);
    gyro << "0.1,0.2,zero,4328041.0\n";  // line 201
  }
  std::string error = conversionError();
  EXPECT_NE(error.find(dir_ + "/gyro.txt:201: wz (rad/s) 'zero' is not a number"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(bag_path_)) << "no bag for unusable input";

  SetUp();
  writeImage(dir_ + "/frames/frame-12.png", false);  // framestamp.txt has lines 0..9
  error = conversionError();
  EXPECT_NE(error.find(dir_ + "/frames: the image files are numbered 3..12 but " + dir_ +
                       "/framestamp.txt has 10 lines, i.e. frames 0..9"),
            std::string::npos)
      << error;

  SetUp();
  writeImage(dir_ + "/frames/frame-x.png", false);
  error = conversionError();
  EXPECT_NE(error.find("frame-x.png: the image name must end in its frame index"), std::string::npos) << error;

  SetUp();
  writeImage(dir_ + "/frames/frame-05.png", false);  // same index as frame-5.png
  error = conversionError();
  EXPECT_NE(error.find("frame index 5 is also the index of"), std::string::npos) << error;

  SetUp();
  std::ofstream(dir_ + "/camera.yaml") << "image_width: [800\n";
  error = conversionError();
  EXPECT_NE(error.find(dir_ + "/camera.yaml: not a ROS camera calibration file"), std::string::npos) << error;

  SetUp();
  writeCalibration(16, 12);
  error = conversionError();
  EXPECT_NE(error.find("frame-3.png: image is 8x6 but the calibration"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(bag_path_)) << "the partly written bag must be removed";

  SetUp();
  writeImage(dir_ + "/frames/frame-6.png", true);
  error = conversionError();
  EXPECT_NE(error.find("frame-6.png: image is mono8 but the first frame"), std::string::npos) << error;

  SetUp();
  options_.frame_stamp_offset_s = 0.9;  // frames 3..6 would end after the last gyro sample
  error = conversionError();
  EXPECT_NE(error.find(dir_ + "/gyro.txt: the gyro samples"), std::string::npos) << error;

  SetUp();
  options_.imu_to_camera_rotation << 0, 1, 0, 1, 0, 0, 0, 0, 1;  // the authors' improper swap
  error = conversionError();
  EXPECT_NE(error.find("not a proper rotation"), std::string::npos) << error;
  EXPECT_NE(error.find("it is a reflection (det -1)"), std::string::npos) << error;
  EXPECT_NE(error.find("rosrun deep_ois calibrate"), std::string::npos) << "say what to do: " << error;

  SetUp();
  std::ofstream(dir_ + "/framestamp.txt", std::ios::app) << "4328040.1\n";  // goes back in time
  error = conversionError();
  EXPECT_NE(error.find(dir_ + "/framestamp.txt:11: stamp"), std::string::npos) << error;
}

// The real phone recording: counts and stamps survive the conversion, and the gyro flow computed
// from the bag alone (IMU, camera_info K, tf R_cam_imu, image stamps) reproduces the authors' own
// homographies within the tolerance of the direct cross-check (test_cc9pro).
TEST(ConvertCc9pro, CountsStampsAndAuthorsHomographies) {
  const std::string dir = test::cc9proDir();
  for (const char* name : {"gyro.txt", "framestamp.txt", "frames", "gyro_homo_h33_source.npy"}) {
    if (!test::fileExists(dir + "/" + name) && !fs::is_directory(dir + "/" + name)) {
      GTEST_SKIP() << "cc9pro recording not found: looked for " << dir << "/" << name
                   << " (set DEEP_OIS_SHARED_DATA to the folder holding cc9pro/)";
    }
  }
  PhoneRecordingFiles files = cc9proLayout(dir);
  files.camera_info = std::string(DEEP_OIS_SOURCE_DIR) + "/config/cameras/cc9pro.yaml";
  const std::string bag_path = ::testing::TempDir() + "/convert_recording_cc9pro.bag";
  const PhoneRecordingBagOptions options;  // the defaults are the cc9pro's
  const PhoneRecordingBagStats stats = writePhoneRecordingBag(files, bag_path, options);
  EXPECT_EQ(stats.frames, 52);
  EXPECT_EQ(stats.first_frame_index, test::kCc9proFirstFrame);
  EXPECT_EQ(stats.last_frame_index, test::kCc9proLastFrame);
  EXPECT_EQ(stats.skipped_frame_indices, 0);
  EXPECT_EQ(stats.encoding, "rgb8");
  EXPECT_EQ(stats.width_px, test::kCc9proWidthPx);
  EXPECT_EQ(stats.height_px, test::kCc9proHeightPx);

  const PhoneRecording recording = loadPhoneRecording(dir);
  const double first_s = recording.frame_stamps_s[test::kCc9proFirstFrame];
  const double last_s = recording.frame_stamps_s[test::kCc9proLastFrame];
  int expected_imu = 0;
  for (const ImuSample& s : recording.gyro) {
    expected_imu += s.stamp_s >= first_s - options.imu_margin_s && s.stamp_s <= last_s + options.imu_margin_s;
  }
  EXPECT_EQ(stats.imu_messages, expected_imu);

  const BagSequence sequence = readBagSequence(bag_path);
  ASSERT_EQ(sequence.frame_stamps.size(), 52u);
  for (int k = 0; k < 52; ++k) {
    // The phone logs stamps in whole microseconds (gyro_dump.txt's SOF lines): the bag keeps them.
    const long long us = std::llround(recording.frame_stamps_s[test::kCc9proFirstFrame + k] * 1e6);
    EXPECT_EQ(sequence.frame_stamps[k], fromMicroseconds(us)) << "frame " << test::kCc9proFirstFrame + k;
  }
  ASSERT_TRUE(sequence.camera.has_value());
  EXPECT_LT((sequence.camera->K() - test::cc9proK()).norm(), 1e-12);
  ASSERT_TRUE(sequence.imu_to_camera_rotation.has_value());

  RollingShutterConfig config = test::authorsConfig();
  config.imu_to_camera_rotation = *sequence.imu_to_camera_rotation;
  const ImuSampleBuffer buffer = sequence.imuBuffer();
  const test::NpyArray reference = test::readNpyFloat64(dir + "/gyro_homo_h33_source.npy");
  test::CornerDifference difference;
  // Pairs n-1 -> n whose both frames are in the bag: n = 100..150.
  for (int n = test::kAuthorsFirstPair; n <= test::kCc9proLastFrame; ++n) {
    const int k = n - test::kCc9proFirstFrame;  // index of frame n in the bag
    const RollingShutterHomographies ours = computeRollingShutterHomographies(
        buffer, test::authorsIntegration(), config, sequence.camera->K(),
        sequence.secondsSinceBase(sequence.frame_stamps[k - 1]), sequence.secondsSinceBase(sequence.frame_stamps[k]));
    ASSERT_TRUE(ours.ok()) << "pair " << n - 1 << "->" << n << ": " << ours.reason;
    for (int patch = 0; patch < 10; ++patch) {
      difference.add(ours.homographies[patch], test::authorsHomography(reference, n, patch));
    }
  }
  std::cout << std::fixed << std::setprecision(6) << "[cc9pro bag] authors' homographies from the converted bag: "
            << "corner difference mean " << difference.meanPx() << " px, max " << difference.max_px << " px over "
            << difference.count << " corners (51 pairs x 10 patches x 4)\n";
  EXPECT_LT(difference.meanPx(), 0.01);  // the tolerances of test_cc9pro
  EXPECT_LT(difference.max_px, 0.05);
  std::remove(bag_path.c_str());
}

}  // namespace
}  // namespace deep_ois
