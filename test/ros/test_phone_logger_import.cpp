// The phone logger importers (convert_recording --format videoimucapture|dvs): hand-made metadata
// files and their malformed variants (always), and the two real recordings of ../shared/data
// (skipped when absent): VideoIMUCapture (HEVC video + video_meta.pb3) and the Pixel 4 DVS logs.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/LU>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <deep_ois/LensShiftSample.h>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/recording/android_camera_orientation.h"
#include "deep_ois/core/recording/dvs_log_recording.h"
#include "deep_ois/core/recording/phone_recording.h"
#include "deep_ois/core/recording/videoimucapture_metadata.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/ros/bag/phone_logger_import.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "run_command.h"
#include "shared_data.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

// ---- A hand-made VideoCaptureData, written field by field. -------------------------------------
struct Protobuf {
  std::string bytes;
  void varint(std::uint64_t v) {
    do {
      std::uint8_t b = v & 0x7f;
      v >>= 7;
      bytes.push_back(static_cast<char>(v ? b | 0x80 : b));
    } while (v);
  }
  void key(int field, int wire) { varint(static_cast<std::uint64_t>(field) << 3 | wire); }
  void integer(int field, std::int64_t v) { key(field, 0), varint(static_cast<std::uint64_t>(v)); }
  void message(int field, const Protobuf& m) { key(field, 2), varint(m.bytes.size()), bytes += m.bytes; }
  void floats(int field, const std::vector<float>& values) {
    key(field, 2);
    varint(values.size() * 4);
    for (float f : values) bytes.append(reinterpret_cast<const char*>(&f), 4);
  }
};

Protobuf size(int w, int h) {
  Protobuf p;
  p.integer(1, w), p.integer(2, h);
  return p;
}

// 30 frames at 30 fps, 200 Hz gyro from 10 ms before the first frame, camera 960x1280 portrait.
std::string tinyVideoCaptureData() {
  Protobuf top, camera;
  camera.floats(1, {993.2f, 993.2f, 479.f, 640.f, 0.f});
  camera.message(11, size(960, 1280));
  camera.message(12, size(4032, 3024));
  camera.integer(14, 90);
  top.message(2, camera);
  const std::int64_t start_ns = 159538623860688LL;
  for (int k = 0; k < 220; ++k) {
    Protobuf imu;
    imu.integer(1, start_ns - 10000000LL + 5000000LL * k);
    imu.floats(2, {0.1f, -0.2f, 0.3f});
    imu.floats(3, {0.01f, 0.0f, 0.0f});
    top.message(4, imu);
  }
  for (int f = 0; f < 30; ++f) {
    Protobuf row;
    row.integer(1, start_ns + 33333333LL * f);
    row.integer(3, 11120870);
    row.integer(5, 32212173);
    Protobuf ois;
    ois.integer(1, start_ns + 33333333LL * f + 1000);
    top.message(5, row);
  }
  return top.bytes;
}

class PhoneLoggerFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/phone_logger_" + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void write(const std::string& name, const std::string& bytes) {
    std::ofstream(dir_ + "/" + name, std::ios::binary) << bytes;
  }
  std::string error(const std::function<void()>& f) {
    try {
      f();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  }
  std::string dir_;
};

TEST_F(PhoneLoggerFiles, VideoCaptureDataIsReadFieldByField) {
  write("video_meta.pb3", tinyVideoCaptureData());
  const VideoImuCaptureMetadata meta = loadVideoImuCaptureMetadata(dir_ + "/video_meta.pb3");
  EXPECT_EQ(meta.width_px, 960);
  EXPECT_EQ(meta.height_px, 1280);
  EXPECT_EQ(meta.active_array_width_px, 4032);
  EXPECT_EQ(meta.sensor_orientation_deg, 90);
  EXPECT_FLOAT_EQ(static_cast<float>(meta.intrinsics[0]), 993.2f);
  ASSERT_EQ(meta.gyro.size(), 220u);
  EXPECT_TRUE(meta.gyro_drift_subtracted);
  EXPECT_NEAR(meta.gyro[0].angular_velocity_rad_s.x(), 0.09, 1e-6);  // gyro - drift
  ASSERT_EQ(meta.frames.size(), 30u);
  EXPECT_NEAR(meta.frames[1].stamp_s - meta.frames[0].stamp_s, 0.033333333, 1e-9);
  EXPECT_NEAR(meta.frames[0].readout_s, 0.032212173, 1e-12);
}

TEST_F(PhoneLoggerFiles, TruncatedProtobufNamesTheFileMessageAndByte) {
  const std::string bytes = tinyVideoCaptureData();
  write("video_meta.pb3", bytes.substr(0, bytes.size() - 7));
  const std::string e = error([&] { loadVideoImuCaptureMetadata(dir_ + "/video_meta.pb3"); });
  EXPECT_NE(e.find(dir_ + "/video_meta.pb3: VideoCaptureData at byte "), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  // Cut in the middle of the gyro rows: the last complete row is named.
  write("video_meta.pb3", bytes.substr(0, bytes.size() / 2));
  const std::string e2 = error([&] { loadVideoImuCaptureMetadata(dir_ + "/video_meta.pb3"); });
  EXPECT_NE(e2.find("truncated"), std::string::npos) << e2;
  EXPECT_NE(e2.find(" imu rows and 0 video_meta rows)"), std::string::npos) << e2;
}

TEST_F(PhoneLoggerFiles, VideoWithoutMetadataAndMetadataWithoutVideoAreSaid) {
  write("imu_sync.mp4", "not decoded: the metadata is missing first");
  std::string output;
  const std::string tool = DEEP_OIS_CONVERT_RECORDING_EXE;
  EXPECT_EQ(test::runCommand(tool + " --quiet --recording " + dir_ + " --out " + dir_ + "/out.bag 2>&1", output), 1);
  EXPECT_NE(output.find(dir_ + "/imu_sync.mp4: a video without metadata"), std::string::npos) << output;

  fs::remove(dir_ + "/imu_sync.mp4");
  write("video_meta.pb3", tinyVideoCaptureData());
  EXPECT_EQ(test::runCommand(tool + " --quiet --recording " + dir_ + " --out " + dir_ + "/out.bag 2>&1", output), 1);
  EXPECT_NE(output.find(dir_ + "/video_meta.pb3: metadata without video: 30 frame rows"), std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(dir_ + "/out.bag"));
  // Asked for explicitly, the metadata alone converts (camera_info per row, gyro).
  EXPECT_EQ(test::runCommand(tool + " --quiet --without-images --recording " + dir_ + " --out " + dir_ +
                                 "/out.bag 2>&1",
                             output),
            0)
      << output;
  EXPECT_NE(output.find("30 frames without images"), std::string::npos) << output;
}

TEST(SensorOrientation, PortraitFramesTurnBackToTheSensorsRows) {
  // A portrait frame whose top-right pixel is marked: on a SENSOR_ORIENTATION 90 sensor the first
  // row read out is the stored frame's right column, top first.
  cv::Mat stored(4, 3, CV_8UC1, cv::Scalar(0));
  stored.at<uint8_t>(0, 2) = 255;
  const SensorOrientationTurn turn = sensorOrientationTurn(90);
  const cv::Mat sensor = turn.apply(stored);
  ASSERT_EQ(sensor.cols, 4);
  ASSERT_EQ(sensor.rows, 3);
  EXPECT_EQ(sensor.at<uint8_t>(0, 0), 255);
  // The principal point moves with the pixels: stored (cx, cy) -> sensor (cy, w - 1 - cx).
  const Eigen::Vector4d k = turn.intrinsics(Eigen::Vector4d(10, 11, 2, 0), cv::Size(3, 4));
  EXPECT_EQ(k, Eigen::Vector4d(11, 10, 0, 0));
  // The gyro: a rotation about the phone's y axis (up in portrait) pans the portrait image
  // horizontally, i.e. moves the sensor image vertically: about the sensor camera's x axis.
  const Eigen::Vector3d camera = androidBackCameraImuToCamera(90) * Eigen::Vector3d(0, 1, 0);
  EXPECT_NEAR(std::abs(camera.x()), 1.0, 1e-12);
  EXPECT_NEAR(androidBackCameraImuToCamera(90).determinant(), 1.0, 1e-12);
}

// ---- The real recordings. ------------------------------------------------------------------------

// VideoIMUCapture (Pixel, HEVC 960x1280 portrait, 635 video frames for 633 metadata rows): the first
// 150 video frames at half size, grey, to keep the test short.
TEST(PhoneRecordingVideoImuCapture, ConvertsWithFramesStampsCameraInfoAndImuOfTheMetadata) {
  const std::string dir = sharedData("videoimucapture_pixel");
  if (!fs::exists(dir + "/video_meta.pb3")) GTEST_SKIP() << "phone recording not found: " << dir;
  VideoImportOptions options;
  options.max_frames = 150;
  options.image_scale = 0.5;
  options.grey = true;
  ImportedRecording imported = importVideoImuCapture(dir + "/imu_sync.mp4", dir + "/video_meta.pb3", options);
  for (const std::string& note : imported.notes) std::printf("%s\n", note.c_str());
  const VideoImuCaptureMetadata meta = loadVideoImuCaptureMetadata(dir + "/video_meta.pb3");
  // The re-encoded video has one frame before the metadata's first row (found by the gyro check).
  ASSERT_FALSE(imported.content.frames.empty());
  EXPECT_EQ(imported.content.frames.front().index, 0);
  EXPECT_NE(imported.content.frames.front().label.find("frame 1 (metadata row 0)"), std::string::npos)
      << imported.content.frames.front().label;
  bool confident = false;
  for (const std::string& note : imported.notes) confident |= note.find("confidence high") != std::string::npos;
  EXPECT_TRUE(confident);
  EXPECT_NEAR(imported.readout_s, 0.0322, 0.0001);

  const std::string bag_path = ::testing::TempDir() + "/videoimucapture.bag";
  PhoneRecordingBagOptions bag_options;
  bag_options.imu_to_camera_rotation = imported.imu_to_camera_rotation;
  bag_options.drop_uncovered_frames = true;  // the gyro starts 5.2 ms after the first row
  const PhoneRecordingBagStats stats = writeRecordingBag(std::move(imported.content), bag_path, bag_options);
  EXPECT_EQ(stats.dropped_uncovered_frames, 1);
  EXPECT_EQ(stats.frames, 148);  // video frames 2..149 = rows 1..148
  EXPECT_EQ(stats.width_px, 640);  // the sensor's orientation: landscape
  EXPECT_EQ(stats.height_px, 480);
  EXPECT_EQ(stats.encoding, "mono8");

  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  int row = 1;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/camera/camera_info"))) {
    const auto info = m.instantiate<sensor_msgs::CameraInfo>();
    ASSERT_TRUE(info);
    EXPECT_NEAR(info->header.stamp.toSec(), meta.frames[static_cast<std::size_t>(row)].stamp_s, 1e-6);
    // fx, fy swap and the principal point turns: cx' = cy, cy' = w - 1 - cx, at half size.
    EXPECT_NEAR(info->K[0], 0.5 * meta.intrinsics[1], 1e-3);
    EXPECT_NEAR(info->K[2], (meta.intrinsics[3] + 0.5) * 0.5 - 0.5, 1e-3);
    EXPECT_NEAR(info->K[5], (960 - 1 - meta.intrinsics[2] + 0.5) * 0.5 - 0.5, 1e-3);
    ++row;
  }
  EXPECT_EQ(row, 149);
  int imu = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/imu/data"))) {
    const auto msg = m.instantiate<sensor_msgs::Imu>();
    ASSERT_TRUE(msg);
    // The gyro as logged minus the phone's drift estimate, on the metadata's clock.
    const auto it = std::find_if(meta.gyro.begin(), meta.gyro.end(), [&](const ImuSample& s) {
      return std::abs(s.stamp_s - msg->header.stamp.toSec()) < 1e-6;
    });
    ASSERT_NE(it, meta.gyro.end());
    EXPECT_NEAR(msg->angular_velocity.x, it->angular_velocity_rad_s.x(), 1e-6);
    ++imu;
  }
  EXPECT_GT(imu, 100);
  bag.close();

  // calibrate on it: accepted only with the readout's 1-sigma interval holding the logged 32.2 ms,
  // the offset within 2 ms of 0 (one clock) and the mount within 2 deg of the Android permutation,
  // or refused with the reason; never accepted with a wrong mount (before: with the readout held
  // and no bias, accepted 17.8 deg off on the whole recording).
  const CalibrationBag calibration_bag = readCalibrationBag(bag_path, CalibrationBagOptions{});
  for (const bool held : {false, true}) {
    CalibrationOptions calibration_options;
    if (held) {
      calibration_options.estimate_readout_time = false;
      calibration_options.readout_time_s = 0.0322;
      calibration_options.estimate_gyro_bias = false;
    }
    const CalibrationResult result = calibrateCameraImu(calibration_bag.data, calibration_options);
    const CameraImuCalibration& c = result.calibration;
    const double mount_deg =
        rotationAngleBetween(c.imu_to_camera_rotation, androidBackCameraImuToCamera(90)) * 180.0 / M_PI;
    std::printf("calibrate (%s): %s; offset %.3f +- %.3f ms, readout %.3f +- %.3f ms, mount %.2f deg from the "
                "permutation (1-sigma %.2f deg), %d iterations%s\n",
                held ? "readout held, no bias" : "all free", result.ok() ? "accepted" : result.reason().c_str(),
                c.time_offset_s * 1e3, c.time_offset_sigma_s * 1e3, c.readout_time_s * 1e3,
                c.readout_time_sigma_s * 1e3, mount_deg, c.rotation_sigma_rad.maxCoeff() * 180.0 / M_PI,
                result.iterations, result.converged ? " (converged)" : " (cap)");
    for (const std::string& note : result.notes) std::printf("  note: %s\n", note.c_str());
    if (result.ok()) {
      EXPECT_LE(mount_deg, 2.0);
      EXPECT_LE(std::abs(c.time_offset_s), 0.002);
      if (!held) {
        EXPECT_LE(std::abs(c.readout_time_s - 0.0322), c.readout_time_sigma_s);
      }
    } else {
      EXPECT_FALSE(result.refusals.empty());
    }
  }
}

// Pixel 4 DVS logs (no video): converted without hand work; the OIS log's repeats are counted.
TEST(PhoneRecordingDvs, Pixel4LogsConvertWithTheLensLogCleaned) {
  const std::string dir = sharedData("pixel4_dvs_ois");
  if (!fs::exists(dir + "/calib.txt")) GTEST_SKIP() << "phone recording not found: " << dir;
  ImportedRecording imported = importDvsLogs(dir, DvsImportOptions{});
  EXPECT_NEAR(imported.readout_s, 0.015980096, 1e-12);
  EXPECT_NEAR(imported.lens_convention.scale, 1920.0 / 4032.0, 1e-12);
  const std::string bag_path = ::testing::TempDir() + "/pixel4_dvs.bag";
  PhoneRecordingBagOptions bag_options;
  bag_options.imu_to_camera_rotation = imported.imu_to_camera_rotation;
  bag_options.drop_uncovered_frames = true;
  const PhoneRecordingBagStats stats = writeRecordingBag(std::move(imported.content), bag_path, bag_options);
  EXPECT_FALSE(stats.images);
  EXPECT_EQ(stats.lens_shift_repeats_dropped, 588);  // README: 588 samples repeat an earlier value
  EXPECT_EQ(stats.lens_shift_steps_back, 295);       // and the stamps go back 295 times
  EXPECT_EQ(stats.frames + stats.dropped_uncovered_frames, 588);
  const BagSequence sequence = readBagSequence(bag_path, {}, BagReadFailure::kThrow, nullptr);
  EXPECT_EQ(static_cast<int>(sequence.frame_stamps.size()), stats.frames);
  EXPECT_EQ(static_cast<int>(sequence.lens_shift_log.size()), stats.lens_shift_messages);
}

}  // namespace
}  // namespace deep_ois
