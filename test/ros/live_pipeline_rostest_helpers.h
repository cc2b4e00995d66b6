// Shared pieces of the live pipeline rostests (live_reliability, live_lag, fuzz_live_pipeline):
// both nodelets in one manager (test/ros/live_pipeline_under_test.launch), fed in real time by the
// test node with a synthetic IMU + camera stream, every output collected, and /rosout read to
// check what the nodelets said.
//
// The frames go to the gyro flow nodelet on /camera/image_raw and to the compensation on
// /compensation_input/image_raw, so that a test can withhold a frame from one of them.
#pragma once

#include <deep_ois/GyroFlow.h>
#include <gtest/gtest.h>
#include <rosgraph_msgs/Log.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "synthetic_camera_messages.h"

namespace deep_ois {
namespace live_test {

constexpr char kImuTopic[] = "/sensors/imu";
constexpr char kImageTopic[] = "/camera/image_raw";
constexpr char kInfoTopic[] = "/camera/camera_info";
constexpr char kCompensationImageTopic[] = "/compensation_input/image_raw";
constexpr char kGyroFlowTopic[] = "/deep_ois/gyro_flow";
constexpr char kCompensatedTopic[] = "/deep_ois/compensated_flow";
using synthetic::kCameraFrame;
using synthetic::kImuFrame;
using synthetic::makeImage;
constexpr int kWidthPx = 320, kHeightPx = 240;
constexpr double kImuPeriodS = 0.0025;  // 400 Hz
constexpr double kFramePeriodS = 1.0 / 30.0;

struct LogLine {
  ros::WallTime received;
  std::string node, text;
  int level = 0;
};

// What a test may change in a frame before it is published, and where it goes.
struct FrameEdit {
  int index = 0;  // frames since the stream started
  sensor_msgs::ImagePtr image;
  sensor_msgs::CameraInfoPtr info;
  bool to_gyro_flow = true, to_compensation = true;
  bool send_info = true;  // camera_info with the frame to the gyro flow
};

// A camera_info of `width` x `height` with a focal length of 0.8 x width, no distortion.
inline sensor_msgs::CameraInfoPtr makeInfo(const ros::Time& stamp, uint32_t width = kWidthPx,
                                           uint32_t height = kHeightPx) {
  const double f = 0.8 * width;
  Eigen::Matrix3d K;
  K << f, 0, 0.5 * width - 0.5, 0, f, 0.5 * height - 0.5, 0, 0, 1;
  return synthetic::makeInfo(stamp, width, height, K);
}

// True when every float of a 32FC2 flow is finite.
inline bool flowIsFinite(const sensor_msgs::Image& flow) {
  for (uint32_t y = 0; y < flow.height; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * flow.step;
    for (uint32_t x = 0; x < 2 * flow.width; ++x) {
      float v;
      std::memcpy(&v, &flow.data[row + 4 * x], sizeof v);
      if (!std::isfinite(v)) return false;
    }
  }
  return true;
}

class LivePipelineHarness {
 public:
  // `subscribe_outputs` false: the harness subscribes to no output of the pipeline (a test that
  // checks what one lone subscriber of its own makes the nodelets do).
  explicit LivePipelineHarness(bool subscribe_outputs = true) : subscribe_outputs_(subscribe_outputs) {
    ros::NodeHandle nh;
    tf_pub_ = nh.advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
    imu_pub_ = nh.advertise<sensor_msgs::Imu>(kImuTopic, 4000);
    image_pub_ = nh.advertise<sensor_msgs::Image>(kImageTopic, 200);
    info_pub_ = nh.advertise<sensor_msgs::CameraInfo>(kInfoTopic, 200);
    compensation_image_pub_ = nh.advertise<sensor_msgs::Image>(kCompensationImageTopic, 200);
    injected_flow_pub_ = nh.advertise<GyroFlow>(kGyroFlowTopic, 100);
    rosout_sub_ = nh.subscribe("/rosout", 5000, &LivePipelineHarness::logCallback, this);
    if (!subscribe_outputs_) return;
    gyro_sub_ = nh.subscribe<GyroFlow>(kGyroFlowTopic, 1000, [this](const GyroFlowConstPtr& m) { onFlow(m, false); });
    compensated_sub_ =
        nh.subscribe<GyroFlow>(kCompensatedTopic, 1000, [this](const GyroFlowConstPtr& m) { onFlow(m, true); });
    for (const char* topic : {"/deep_ois/gyro_flow/color", "/deep_ois/compensated_flow/color",
                              "/deep_ois/aligned/image_raw", "/deep_ois/aligned/ghost"}) {
      image_subs_.push_back(nh.subscribe<sensor_msgs::Image>(topic, 1000, [this, topic](const sensor_msgs::ImageConstPtr&) {
        std::lock_guard<std::mutex> lock(mutex_);
        ++image_outputs_[topic];
      }));
    }
  }

  void publishTf() {
    geometry_msgs::TransformStamped t;
    t.header.stamp = ros::Time::now();
    t.header.frame_id = kImuFrame;
    t.child_frame_id = kCameraFrame;
    // Camera optical frame on an x-forward IMU: R_imu_cam columns are the camera axes in the IMU.
    Eigen::Matrix3d R_imu_cam;
    R_imu_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    const Eigen::Quaterniond q(R_imu_cam);
    t.transform.rotation.w = q.w();
    t.transform.rotation.x = q.x();
    t.transform.rotation.y = q.y();
    t.transform.rotation.z = q.z();
    tf2_msgs::TFMessage msg;
    msg.transforms.push_back(t);
    tf_pub_.publish(msg);
  }

  // Waits until both nodelets listen to the inputs and publish to us (when we subscribe).
  // `tf_needed` false: the nodelets were given ~imu_to_camera_rotation, so none listens to the tf.
  ::testing::AssertionResult waitForPipeline(double timeout_s = 60.0, bool tf_needed = true) {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
    auto ready = [&] {
      return imu_pub_.getNumSubscribers() > 0 && image_pub_.getNumSubscribers() > 0 &&
             info_pub_.getNumSubscribers() > 0 && compensation_image_pub_.getNumSubscribers() > 0 &&
             (!tf_needed || tf_pub_.getNumSubscribers() > 0) &&
             (!subscribe_outputs_ || (gyro_sub_.getNumPublishers() > 0 && compensated_sub_.getNumPublishers() > 0));
    };
    while (!ready() && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
    if (!ready()) return ::testing::AssertionFailure() << "the pipeline did not connect within " << timeout_s << " s";
    ros::WallDuration(0.5).sleep();
    return ::testing::AssertionSuccess();
  }

  // Streams IMU at 400 Hz and frames at 30 fps in real time for `duration_s` (stamps: ROS time of
  // publication). `edit_frame` may change a frame or withhold it; `edit_imu` an IMU message
  // (false: withhold it).
  void stream(double duration_s, const std::function<void(FrameEdit&)>& edit_frame = {},
              const std::function<bool(sensor_msgs::Imu&)>& edit_imu = {}) {
    const ros::WallTime start = ros::WallTime::now();
    ros::WallTime next_frame = start;
    while (true) {
      const ros::WallTime now = ros::WallTime::now();
      if ((now - start).toSec() >= duration_s) break;
      const ros::Time stamp = ros::Time::now() + stamp_shift_;
      auto imu = boost::make_shared<sensor_msgs::Imu>();
      imu->header.stamp = stamp;
      imu->header.frame_id = kImuFrame;
      imu->orientation_covariance[0] = -1.0;
      const double t = (now - start).toSec();
      imu->angular_velocity.x = 0.2 * std::sin(3.0 * t);
      imu->angular_velocity.y = 0.3;
      imu->angular_velocity.z = -0.1 + 0.2 * std::cos(2.0 * t);
      if (!edit_imu || edit_imu(*imu)) imu_pub_.publish(imu);
      if (now >= next_frame) {
        next_frame += ros::WallDuration(kFramePeriodS);
        FrameEdit edit;
        edit.index = frame_index_++;
        edit.image = makeImage(stamp, kWidthPx, kHeightPx);
        edit.info = makeInfo(stamp);
        if (edit_frame) edit_frame(edit);
        if (edit.to_gyro_flow) {
          image_pub_.publish(edit.image);
          if (edit.send_info) info_pub_.publish(edit.info);
        }
        if (edit.to_compensation) compensation_image_pub_.publish(edit.image);
        std::lock_guard<std::mutex> lock(mutex_);
        if (edit.to_gyro_flow || edit.to_compensation) frame_publish_times_.push_back(ros::WallTime::now());
      }
      ros::WallDuration(kImuPeriodS).sleep();
    }
  }

  // A constant added to the stamps of everything streamed from now on (a time jump).
  void shiftStamps(const ros::Duration& shift) { stamp_shift_ += shift; }

  void injectFlow(const GyroFlow& flow) { injected_flow_pub_.publish(flow); }

  // Outputs received within [from, to) (wall time of arrival).
  std::size_t countBetween(bool compensated, const ros::WallTime& from, const ros::WallTime& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& arrivals = compensated ? compensated_arrivals_ : gyro_arrivals_;
    return std::count_if(arrivals.begin(), arrivals.end(),
                         [&](const ros::WallTime& t) { return t >= from && t < to; });
  }
  std::size_t framesBetween(const ros::WallTime& from, const ros::WallTime& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::count_if(frame_publish_times_.begin(), frame_publish_times_.end(),
                         [&](const ros::WallTime& t) { return t >= from && t < to; });
  }
  // Delay from stamp to arrival of each compensated flow received within [from, to), seconds.
  std::vector<double> compensatedDelaysBetween(const ros::WallTime& from, const ros::WallTime& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<double> delays;
    for (std::size_t k = 0; k < compensated_arrivals_.size(); ++k) {
      if (compensated_arrivals_[k] >= from && compensated_arrivals_[k] < to) delays.push_back(compensated_delays_s_[k]);
    }
    return delays;
  }
  // Images received so far on one of the image outputs (gyro_flow/color, compensated_flow/color,
  // aligned/image_raw, aligned/ghost under /deep_ois).
  std::size_t imageOutputs(const std::string& topic) {
    std::lock_guard<std::mutex> lock(mutex_);
    return image_outputs_[topic];
  }
  GyroFlowConstPtr lastGyroFlow() {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_gyro_flow_;
  }
  std::size_t nonFiniteOutputs() {
    std::lock_guard<std::mutex> lock(mutex_);
    return non_finite_;
  }

  // Warnings (or worse) from the pipeline's nodes received since `since` whose text holds every
  // one of `parts`.
  std::vector<LogLine> warnings(const ros::WallTime& since, const std::vector<std::string>& parts) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<LogLine> found;
    for (const LogLine& line : log_) {
      if (line.received < since || line.level < rosgraph_msgs::Log::WARN) continue;
      if (line.node.find("deep_ois") == std::string::npos) continue;
      bool all = true;
      for (const std::string& p : parts) all = all && line.text.find(p) != std::string::npos;
      if (all) found.push_back(line);
    }
    return found;
  }
  std::string warningsText(const ros::WallTime& since) {
    std::string text;
    for (const LogLine& l : warnings(since, {})) text += "  " + l.text + "\n";
    return text;
  }

 private:
  void onFlow(const GyroFlowConstPtr& msg, bool compensated) {
    const ros::WallTime now = ros::WallTime::now();
    const double delay_s = (ros::Time::now() - msg->header.stamp).toSec();
    std::lock_guard<std::mutex> lock(mutex_);
    if (!flowIsFinite(msg->flow)) ++non_finite_;
    if (compensated) {
      compensated_arrivals_.push_back(now);
      compensated_delays_s_.push_back(delay_s);
    } else if (msg->header.frame_id == kCameraFrame && msg->image_width == kWidthPx) {
      gyro_arrivals_.push_back(now);
      last_gyro_flow_ = msg;
    }
  }
  void logCallback(const rosgraph_msgs::LogConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    log_.push_back({ros::WallTime::now(), msg->name, msg->msg, msg->level});
  }

  bool subscribe_outputs_;
  ros::Publisher tf_pub_, imu_pub_, image_pub_, info_pub_, compensation_image_pub_, injected_flow_pub_;
  ros::Subscriber rosout_sub_, gyro_sub_, compensated_sub_;
  std::vector<ros::Subscriber> image_subs_;
  std::mutex mutex_;
  std::vector<ros::WallTime> gyro_arrivals_, compensated_arrivals_, frame_publish_times_;
  std::vector<double> compensated_delays_s_;
  std::map<std::string, std::size_t> image_outputs_;
  GyroFlowConstPtr last_gyro_flow_;
  std::size_t non_finite_ = 0;
  std::vector<LogLine> log_;
  int frame_index_ = 0;
  ros::Duration stamp_shift_;
};

// main() of a live-pipeline rostest node: the spinner serves the harness's subscriptions while the
// tests publish; `harness` points at the one harness while the tests run.
inline int runLivePipelineGtests(int argc, char** argv, const char* node_name,
                                 LivePipelineHarness*& harness, bool subscribe_outputs = true) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::NodeHandle nh;  // starts the node before the spinner, keeps it up between tests
  ros::AsyncSpinner spinner(2);
  spinner.start();
  LivePipelineHarness instance(subscribe_outputs);
  harness = &instance;
  const int result = RUN_ALL_TESTS();
  harness = nullptr;
  return result;
}

}  // namespace live_test
}  // namespace deep_ois
