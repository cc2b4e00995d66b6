// Shared pieces of the gyro flow rostests: an analytic camera motion, an independent reference for
// the homographies it implies, a synthetic IMU + camera stream, and the checks of a GyroFlow.
//
// The reference deliberately does not call the core library (computeRollingShutterHomographies,
// integrateRotation, HomographyFlowRenderer): it integrates the analytic rate with RK4 at a tiny
// step and derives H from first principles, so a convention error in the core and the wrapper
// cannot cancel out in the test.
#pragma once

#include <deep_ois/GyroFlow.h>
#include <deep_ois/LensShiftSample.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "synthetic_camera_messages.h"

namespace deep_ois {
namespace rostest_helpers {

// Topics and names shared with the .test files.
constexpr char kNodeletNamespace[] = "/deep_ois/gyro_flow";  // private namespace of the nodelet
constexpr char kFlowTopic[] = "/deep_ois/gyro_flow";
constexpr char kColorTopic[] = "/deep_ois/gyro_flow/color";
constexpr char kImuTopic[] = "/sensors/imu";
constexpr char kImageTopic[] = "/camera/image_raw";
constexpr char kInfoTopic[] = "/camera/camera_info";
constexpr char kLensShiftTopic[] = "/camera/lens_shift";  // the camera's lens log (remapped in .test)
using synthetic::kCameraFrame;
using synthetic::kImuFrame;
using synthetic::makeImage;

constexpr int kImageWidthPx = 320;
constexpr int kImageHeightPx = 240;
constexpr double kImuPeriodS = 0.0025;  // 400 Hz
constexpr double kFramePeriodS = 1.0 / 30.0;

inline Eigen::Matrix3d syntheticK() {
  Eigen::Matrix3d K;
  K << 250.0, 0.0, 161.3, 0.0, 252.0, 118.7, 0.0, 0.0, 1.0;
  return K;
}

// R_cam_imu of a typical mount (IMU x forward, y left, z up; camera optical z forward, x right,
// y down) that is a few degrees off: a signed axis permutation times a small rotation, so that a
// transposed, inverted or ignored rotation shows up in the homographies.
inline Eigen::Matrix3d syntheticImuToCamera() {
  Eigen::Matrix3d permutation;
  permutation << 0, -1, 0,  //
      0, 0, -1,             //
      1, 0, 0;
  const double deg = M_PI / 180.0;
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(3.0 * deg, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(-2.0 * deg, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(4.0 * deg, Eigen::Vector3d::UnitZ()))
                                   .toRotationMatrix();
  return permutation * tilt;
}

// Camera-frame body rate w_cam(t) = (a, b + c (t - t_ref), d) rad/s. The y rate (pan) changes with
// time, so the rotation between two frames depends on when each row patch is read out: a wrapper
// that ignored readout_time or time_offset would be off by tenths of a pixel.
struct LinearRateMotion {
  ros::Time reference_stamp;
  Eigen::Vector3d rate_at_reference_rad_s{0.2, 0.5, 0.3};
  double pan_acceleration_rad_s2 = 2.0;

  // Rate at `tau_s` seconds after reference_stamp, camera frame.
  Eigen::Vector3d cameraRate(double tau_s) const {
    return rate_at_reference_rad_s + Eigen::Vector3d(0.0, pan_acceleration_rad_s2 * tau_s, 0.0);
  }
  double tau(const ros::Time& stamp) const { return (stamp - reference_stamp).toSec(); }

  // delta = R_cam(t0)^T R_cam(t1), R_cam(t) mapping camera vectors to the world, from
  // dR/dt = R [w_cam]x, integrated by classical RK4 on the unit quaternion with steps of at most
  // 10 us (the local error, ~(w h)^5, is far below double rounding).
  Eigen::Matrix3d cameraRotationChange(double tau0_s, double tau1_s) const {
    const int steps = std::max(1, static_cast<int>(std::ceil(std::abs(tau1_s - tau0_s) / 1e-5)));
    const double h = (tau1_s - tau0_s) / steps;
    // q' = 0.5 q (0, w): body rates multiply on the right.
    auto derivative = [this](const Eigen::Vector4d& q, double tau) {
      const Eigen::Quaterniond dq = Eigen::Quaterniond(q(3), q(0), q(1), q(2)) *
                                    Eigen::Quaterniond(0.0, cameraRate(tau).x(), cameraRate(tau).y(),
                                                       cameraRate(tau).z());
      return Eigen::Vector4d(0.5 * dq.coeffs());
    };
    Eigen::Vector4d q(0.0, 0.0, 0.0, 1.0);  // x, y, z, w
    for (int k = 0; k < steps; ++k) {
      const double tau = tau0_s + k * h;
      const Eigen::Vector4d k1 = derivative(q, tau);
      const Eigen::Vector4d k2 = derivative(q + 0.5 * h * k1, tau + 0.5 * h);
      const Eigen::Vector4d k3 = derivative(q + 0.5 * h * k2, tau + 0.5 * h);
      const Eigen::Vector4d k4 = derivative(q + h * k3, tau + h);
      q += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    q.normalize();
    return Eigen::Quaterniond(q(3), q(0), q(1), q(2)).toRotationMatrix();
  }
};

// The rolling-shutter timing the nodelet was configured with (patch_time = centre).
struct RollingShutterTiming {
  int patch_count = 0;
  double readout_time_s = 0.0;
  double time_offset_s = 0.0;

  // IMU time of patch i of a frame stamped `stamp`, seconds after motion.reference_stamp.
  double patchTau(const LinearRateMotion& motion, const ros::Time& stamp, int patch) const {
    return motion.tau(stamp) + time_offset_s + readout_time_s * (patch + 0.5) / patch_count;
  }
  // [first, last] IMU time the pair needs.
  std::pair<double, double> imuInterval(const LinearRateMotion& motion, const ros::Time& stamp_a,
                                        const ros::Time& stamp_b) const {
    return {patchTau(motion, stamp_a, 0), patchTau(motion, stamp_b, patch_count - 1)};
  }
};

// Reads the timing from the nodelet's private parameters: the test must agree with the nodelet's
// configuration without repeating numbers that the .test file already states.
inline ::testing::AssertionResult readTiming(RollingShutterTiming& timing) {
  const std::string ns = kNodeletNamespace;
  std::string patch_time;
  if (!ros::param::get(ns + "/patch_count", timing.patch_count) ||
      !ros::param::get(ns + "/readout_time", timing.readout_time_s) ||
      !ros::param::get(ns + "/time_offset", timing.time_offset_s) ||
      !ros::param::get(ns + "/patch_time", patch_time)) {
    return ::testing::AssertionFailure() << "the .test file must set patch_count, readout_time, "
                                            "time_offset and patch_time under "
                                         << ns;
  }
  if (patch_time != "centre") return ::testing::AssertionFailure() << "tests assume patch_time centre";
  return ::testing::AssertionSuccess();
}

// Expected H_i: a static world point X seen at X_a = R_cam(t_a)^T X in frame a is at
// X_b = R_cam(t_b)^T X = delta^T X_a in frame b, so H_i = K delta^T K^-1 with H[2][2] = 1.
inline std::vector<Eigen::Matrix3d> expectedHomographies(const LinearRateMotion& motion,
                                                         const RollingShutterTiming& timing,
                                                         const Eigen::Matrix3d& K,
                                                         const ros::Time& stamp_a,
                                                         const ros::Time& stamp_b) {
  std::vector<Eigen::Matrix3d> result;
  const double interval_s = (stamp_b - stamp_a).toSec();
  for (int i = 0; i < timing.patch_count; ++i) {
    const double tau_a = timing.patchTau(motion, stamp_a, i);
    const Eigen::Matrix3d delta = motion.cameraRotationChange(tau_a, tau_a + interval_s);
    Eigen::Matrix3d H = K * delta.transpose() * K.inverse();
    result.push_back(H / H(2, 2));
  }
  return result;
}

inline Eigen::Vector2d applyHomography(const Eigen::Matrix3d& H, const Eigen::Vector2d& p) {
  return (H * p.homogeneous()).hnormalized();
}

inline Eigen::Matrix3d rowMajor(const double* values) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = values[3 * r + c];
  return m;
}

inline std::vector<Eigen::Matrix3d> homographiesOf(const GyroFlow& msg) {
  std::vector<Eigen::Matrix3d> result;
  for (std::size_t i = 0; 9 * (i + 1) <= msg.homographies.size(); ++i) {
    result.push_back(rowMajor(&msg.homographies[9 * i]));
  }
  return result;
}

// Image corners and centre, camera pixels.
inline std::vector<Eigen::Vector2d> probePixels() {
  const double w = kImageWidthPx - 1.0, h = kImageHeightPx - 1.0;
  return {{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}, {0.5 * w, 0.5 * h}};
}

// How far a homography is from its expectation: Frobenius norm of the difference relative to the
// expectation's, and the largest distance between the images of the corners and the centre.
struct HomographyError {
  double relative = 0.0;
  double pixel_px = 0.0;
};
inline HomographyError homographyError(const Eigen::Matrix3d& expected, const Eigen::Matrix3d& actual) {
  HomographyError error;
  error.relative = (expected - actual).norm() / expected.norm();
  for (const Eigen::Vector2d& p : probePixels()) {
    error.pixel_px =
        std::max(error.pixel_px, (applyHomography(expected, p) - applyHomography(actual, p)).norm());
  }
  return error;
}

// Passes when every H_i agrees with the expectation to 1e-6 relative (Frobenius) and maps the
// corners and the centre within `max_pixel_error_px`.
inline ::testing::AssertionResult homographiesMatch(const std::vector<Eigen::Matrix3d>& expected,
                                                    const std::vector<Eigen::Matrix3d>& actual,
                                                    double max_relative_error = 1e-6,
                                                    double max_pixel_error_px = 0.01) {
  if (expected.size() != actual.size()) {
    return ::testing::AssertionFailure() << "expected " << expected.size() << " homographies, got "
                                         << actual.size();
  }
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const auto [relative, pixel_error] = homographyError(expected[i], actual[i]);
    if (!(relative <= max_relative_error) || !(pixel_error <= max_pixel_error_px)) {
      return ::testing::AssertionFailure()
             << "patch " << i << ": relative error " << relative << ", corner error " << pixel_error
             << " px\nexpected:\n"
             << expected[i] << "\nactual:\n"
             << actual[i];
    }
  }
  return ::testing::AssertionSuccess();
}

// Checks everything a GyroFlow states besides its homographies, and that its flow is the
// homographies applied on the grid. `grid_size` in grid pixels.
inline ::testing::AssertionResult metadataAndFlowMatch(const GyroFlow& msg, const ros::Time& stamp_a,
                                                       const RollingShutterTiming& timing,
                                                       const Eigen::Matrix3d& K,
                                                       const Eigen::Matrix3d& R_cam_imu,
                                                       int grid_width_px, int grid_height_px) {
  auto fail = [&msg]() {
    return ::testing::AssertionFailure() << "GyroFlow " << msg.header.stamp << ": ";
  };
  if (msg.header.frame_id != kCameraFrame) return fail() << "frame_id '" << msg.header.frame_id << "'";
  if (msg.previous_stamp != stamp_a) {
    return fail() << "previous_stamp " << msg.previous_stamp << ", expected " << stamp_a;
  }
  if (msg.image_width != kImageWidthPx || msg.image_height != kImageHeightPx) {
    return fail() << "image size " << msg.image_width << "x" << msg.image_height;
  }
  if (static_cast<int>(msg.patch_count) != timing.patch_count ||
      msg.homographies.size() != 9u * timing.patch_count) {
    return fail() << "patch_count " << msg.patch_count << " with " << msg.homographies.size()
                  << " homography values";
  }
  if (rowMajor(msg.K.data()) != K) return fail() << "K\n" << rowMajor(msg.K.data());
  if (msg.distortion_model != "plumb_bob") return fail() << "distortion_model " << msg.distortion_model;
  // Zero plumb_bob coefficients may be stated or left out; either means no distortion.
  for (double d : msg.D) {
    if (d != 0.0) return fail() << "non-zero distortion coefficient " << d;
  }
  if (msg.readout_time != timing.readout_time_s || msg.time_offset != timing.time_offset_s ||
      msg.patch_time_fraction != 0.5) {
    return fail() << "timing " << msg.readout_time << " / " << msg.time_offset << " / "
                  << msg.patch_time_fraction;
  }
  const Eigen::Matrix3d rotation = rowMajor(msg.imu_to_camera_rotation.data());
  if (!rotation.isApprox(R_cam_imu, 1e-9)) {
    return fail() << "imu_to_camera_rotation\n" << rotation << "\nexpected\n" << R_cam_imu;
  }

  const sensor_msgs::Image& flow = msg.flow;
  if (flow.encoding != "32FC2" || static_cast<int>(flow.width) != grid_width_px ||
      static_cast<int>(flow.height) != grid_height_px || flow.step < flow.width * 8u ||
      flow.data.size() < static_cast<std::size_t>(flow.step) * flow.height || flow.is_bigendian) {
    return fail() << "flow is " << flow.width << "x" << flow.height << " '" << flow.encoding
                  << "', step " << flow.step << ", " << flow.data.size() << " bytes";
  }
  if (flow.header.stamp != msg.header.stamp || flow.header.frame_id != msg.header.frame_id) {
    return fail() << "flow header differs from the message header";
  }
  // Grid pixel g stands for camera pixel p = (g + 0.5) s - 0.5; the flow is (H_i p - p) / s with
  // i the patch of p's row (rows [i h/N, (i+1) h/N)). Float storage: 1e-3 grid px is ample.
  const std::vector<Eigen::Matrix3d> homographies = homographiesOf(msg);
  const Eigen::Vector2d scale(static_cast<double>(kImageWidthPx) / grid_width_px,
                              static_cast<double>(kImageHeightPx) / grid_height_px);
  double worst_px = 0.0;
  for (int gy = 0; gy < grid_height_px; ++gy) {
    const double y = (gy + 0.5) * scale.y() - 0.5;
    const int patch = std::min(timing.patch_count - 1,
                               static_cast<int>(std::floor(y / (static_cast<double>(kImageHeightPx) /
                                                                timing.patch_count))));
    const float* row = reinterpret_cast<const float*>(&flow.data[static_cast<std::size_t>(gy) * flow.step]);
    for (int gx = 0; gx < grid_width_px; ++gx) {
      const Eigen::Vector2d p((gx + 0.5) * scale.x() - 0.5, y);
      const Eigen::Vector2d expected =
          (applyHomography(homographies[patch], p) - p).cwiseQuotient(scale);
      const Eigen::Vector2d actual(row[2 * gx], row[2 * gx + 1]);
      const double error = (expected - actual).norm();
      worst_px = std::isfinite(error) ? std::max(worst_px, error) : INFINITY;
    }
  }
  if (!(worst_px <= 1e-3)) return fail() << "flow differs from its homographies by " << worst_px << " grid px";
  return ::testing::AssertionSuccess();
}

// One message of the synthetic stream, published when the stream clock reaches publish_key_s.
struct StreamEvent {
  double publish_key_s = 0.0;
  sensor_msgs::ImuPtr imu;            // set for IMU events
  sensor_msgs::ImagePtr image;        // set, with info, for camera events
  sensor_msgs::CameraInfoPtr info;
  LensShiftSamplePtr lens;            // set for lens-shift log events
};

inline void sortByPublishKey(std::vector<StreamEvent>& events) {
  std::stable_sort(events.begin(), events.end(), [](const StreamEvent& a, const StreamEvent& b) {
    return a.publish_key_s < b.publish_key_s;
  });
}

// An Imu message carrying only the gyro: rate in the message's frame.
inline sensor_msgs::ImuPtr makeImu(const ros::Time& stamp, const std::string& frame_id,
                                   const Eigen::Vector3d& rate_rad_s) {
  auto imu = boost::make_shared<sensor_msgs::Imu>();
  imu->header.stamp = stamp;
  imu->header.frame_id = frame_id;
  imu->orientation_covariance[0] = -1.0;  // no orientation estimate
  imu->angular_velocity.x = rate_rad_s.x();
  imu->angular_velocity.y = rate_rad_s.y();
  imu->angular_velocity.z = rate_rad_s.z();
  imu->linear_acceleration.z = 9.81;
  return imu;
}

// The synthetic camera's camera_info: K = syntheticK(), no distortion.
inline sensor_msgs::CameraInfoPtr makeInfo(const ros::Time& stamp) {
  return synthetic::makeInfo(stamp, kImageWidthPx, kImageHeightPx, syntheticK());
}

// IMU events of `motion` every 2.5 ms from its reference stamp up to stream time end_tau_s (stamps
// exact in nanoseconds), rates rotated into the IMU frame, each published lead_s before its stamp.
inline void appendImuEvents(const LinearRateMotion& motion, const Eigen::Matrix3d& R_cam_imu, double end_tau_s,
                            double lead_s, std::vector<StreamEvent>& events) {
  for (int k = 0; k * 0.0025 <= end_tau_s; ++k) {
    const ros::Time stamp = motion.reference_stamp + ros::Duration(0, 2500000) * k;
    StreamEvent event;
    event.publish_key_s = motion.tau(stamp) - lead_s;
    event.imu = makeImu(stamp, kImuFrame, R_cam_imu.transpose() * motion.cameraRate(motion.tau(stamp)));
    events.push_back(event);
  }
}

// A camera event (image and camera_info) per stamp, published at the stamp's stream time.
inline void appendFrameEvents(const LinearRateMotion& motion, const std::vector<ros::Time>& frame_stamps,
                              std::vector<StreamEvent>& events) {
  for (const ros::Time& stamp : frame_stamps) {
    StreamEvent event;
    event.publish_key_s = motion.tau(stamp);
    event.image = makeImage(stamp, kImageWidthPx, kImageHeightPx);
    event.info = makeInfo(stamp);
    events.push_back(event);
  }
}

// Publishes the inputs of the nodelet and collects its outputs. Callbacks run on the global queue
// served by the AsyncSpinner that main() starts; `mutex_` guards the collected messages.
class GyroFlowHarness {
 public:
  explicit GyroFlowHarness(bool subscribe_color) {
    ros::NodeHandle nh;
    // /tf_static is published through a plain latched publisher (what StaticTransformBroadcaster
    // does) so that the test can see when the nodelet's tf listener has connected.
    tf_pub_ = nh.advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
    imu_pub_ = nh.advertise<sensor_msgs::Imu>(kImuTopic, 4000);
    image_pub_ = nh.advertise<sensor_msgs::Image>(kImageTopic, 200);
    info_pub_ = nh.advertise<sensor_msgs::CameraInfo>(kInfoTopic, 200);
    lens_pub_ = nh.advertise<LensShiftSample>(kLensShiftTopic, 4000);
    flow_sub_ = nh.subscribe(kFlowTopic, 1000, &GyroFlowHarness::flowCallback, this);
    if (subscribe_color) color_sub_ = nh.subscribe(kColorTopic, 1000, &GyroFlowHarness::colorCallback, this);
  }

  // Mounts the camera on the IMU: parent imu_link, child camera_optical_frame, i.e. the transform
  // holds R_imu_cam = R_cam_imu^T; the nodelet must invert it.
  void publishStaticTransform(const Eigen::Matrix3d& R_cam_imu) {
    tf2_msgs::TFMessage message;
    geometry_msgs::TransformStamped transform;
    transform.header.stamp = ros::Time::now();
    transform.header.frame_id = kImuFrame;
    transform.child_frame_id = kCameraFrame;
    transform.transform.translation.x = 0.02;
    transform.transform.translation.z = 0.01;
    const Eigen::Quaterniond q(Eigen::Matrix3d(R_cam_imu.transpose()));
    transform.transform.rotation.x = q.x();
    transform.transform.rotation.y = q.y();
    transform.transform.rotation.z = q.z();
    transform.transform.rotation.w = q.w();
    message.transforms.push_back(transform);
    tf_pub_.publish(message);
  }

  // Waits until the nodelet listens to every input and publishes to us: it subscribes its inputs
  // only once its output has a subscriber, so streaming earlier would lose the first messages.
  // `expect_image_subscriber` false: the nodelet runs from camera_info alone.
  ::testing::AssertionResult waitForNodelet(double timeout_s, bool expect_image_subscriber = true) {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::ok() && ros::WallTime::now() < deadline) {
      if (tf_pub_.getNumSubscribers() > 0 && imu_pub_.getNumSubscribers() > 0 &&
          (image_pub_.getNumSubscribers() > 0) == expect_image_subscriber && info_pub_.getNumSubscribers() > 0 &&
          flow_sub_.getNumPublishers() > 0 && (!color_sub_ || color_sub_.getNumPublishers() > 0)) {
        return ::testing::AssertionSuccess();
      }
      ros::WallDuration(0.05).sleep();
    }
    return ::testing::AssertionFailure()
           << "after " << timeout_s << " s the nodelet still does not listen: subscribers of tf_static "
           << tf_pub_.getNumSubscribers() << ", imu " << imu_pub_.getNumSubscribers() << ", image "
           << image_pub_.getNumSubscribers() << ", camera_info " << info_pub_.getNumSubscribers()
           << "; publishers of gyro_flow " << flow_sub_.getNumPublishers();
  }

  // With use_sim_time: play() also drives /clock, as `rosbag play --clock` does, at
  // origin + publish key before each event. Until play() starts, ROS time stays 0.
  void driveClock(const ros::Time& origin) {
    clock_pub_ = ros::NodeHandle().advertise<rosgraph_msgs::Clock>("/clock", 100);
    clock_origin_ = origin;
  }

  // Publishes the events in order, `speed` times faster than their publish keys.
  void play(const std::vector<StreamEvent>& events, double speed) {
    if (events.empty()) return;
    const ros::WallTime start = ros::WallTime::now();
    const double first_key_s = events.front().publish_key_s;
    for (const StreamEvent& event : events) {
      const ros::WallTime due = start + ros::WallDuration((event.publish_key_s - first_key_s) / speed);
      const ros::WallTime now = ros::WallTime::now();
      if (due > now) (due - now).sleep();
      if (clock_pub_) {
        rosgraph_msgs::Clock clock;
        clock.clock = clock_origin_ + ros::Duration(event.publish_key_s);
        clock_pub_.publish(clock);
      }
      if (event.imu) imu_pub_.publish(event.imu);
      if (event.lens) lens_pub_.publish(event.lens);
      if (event.image) {
        image_pub_.publish(event.image);
        info_pub_.publish(event.info);
      }
    }
  }

  // Waits until `done` holds for the collected flows or the timeout passes; returns `done`.
  bool waitForFlows(const std::function<bool(const std::vector<GyroFlowConstPtr>&)>& done,
                    double timeout_s) {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::ok()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (done(flows_)) return true;
      }
      if (ros::WallTime::now() > deadline) return false;
      ros::WallDuration(0.02).sleep();
    }
    return false;
  }

  std::size_t imageSubscribers() const { return image_pub_.getNumSubscribers(); }
  std::size_t lensShiftSubscribers() const { return lens_pub_.getNumSubscribers(); }

  std::vector<GyroFlowConstPtr> flows() {
    std::lock_guard<std::mutex> lock(mutex_);
    return flows_;
  }
  std::vector<sensor_msgs::ImageConstPtr> colors() {
    std::lock_guard<std::mutex> lock(mutex_);
    return colors_;
  }

 private:
  void flowCallback(const GyroFlowConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    flows_.push_back(msg);
  }
  void colorCallback(const sensor_msgs::ImageConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    colors_.push_back(msg);
  }

  ros::Publisher tf_pub_, imu_pub_, image_pub_, info_pub_, lens_pub_, clock_pub_;
  ros::Time clock_origin_;
  ros::Subscriber flow_sub_, color_sub_;
  std::mutex mutex_;
  std::vector<GyroFlowConstPtr> flows_;
  std::vector<sensor_msgs::ImageConstPtr> colors_;
};

// Grid size from the nodelet's parameters.
inline ::testing::AssertionResult readGridSize(int& width_px, int& height_px) {
  const std::string ns = kNodeletNamespace;
  if (!ros::param::get(ns + "/grid_width", width_px) || !ros::param::get(ns + "/grid_height", height_px)) {
    return ::testing::AssertionFailure() << "the .test file must set grid_width and grid_height";
  }
  return ::testing::AssertionSuccess();
}

// main() of a rostest gtest node: the spinner serves the subscriptions while the tests publish.
inline int runRostestGtests(int argc, char** argv, const char* node_name) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::NodeHandle nh;  // starts the node before the spinner, keeps it up between tests
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}

}  // namespace rostest_helpers
}  // namespace deep_ois
