// rostest of the deep_ois/gyro_flow nodelet with the camera's lens-shift log: a known lens
// trajectory s(t), logged at 500 Hz in a camera convention (scale, axis swap, sign, clock offset),
// delivered late, with two gaps. Where the log covers a pair the published homographies must be
// K(s(t_b,i)) R_i K(s(t_a,i))^-1 to 0.01 px (motion_model gyro+lens_log); where a gap falls inside
// the pair, the gyro alone K R_i K^-1 (motion_model gyro), no pair lost, and one throttled warning
// for the lot. The expectation is computed here from the analytic motion and trajectory, not by
// the core library.
#include <rosgraph_msgs/Log.h>

#include <iostream>
#include <map>

#include "gyro_flow_rostest_helpers.h"

namespace deep_ois {
namespace {

using namespace rostest_helpers;

constexpr int kFrameCount = 45;
constexpr double kImuLeadS = 0.05;
constexpr double kLensLatencyS =
    0.02;  // the log is delivered this long after the instant (stamp time)
constexpr double kLensPeriodS = 0.002;  // 500 Hz
constexpr double kPlaybackSpeed = 3.0;
constexpr double kGapS = 0.03;  // each gap: 15 samples lost (> ~lens_shift_max_gap 0.01 s)

// The lens trajectory, camera clock (seconds after the motion's reference), published-image px.
Eigen::Vector2d trueShift(double tau_s) {
  return {1.0 + 4.0 * std::sin(2.0 * M_PI * 3.0 * tau_s),
          -0.5 + 3.0 * std::cos(2.0 * M_PI * 2.0 * tau_s)};
}

// The camera convention of the .test file.
struct Convention {
  Eigen::Matrix2d matrix;  // image px = matrix * logged
  double time_offset_s = 0.0;
};

::testing::AssertionResult readConvention(Convention& c) {
  const std::string ns = kNodeletNamespace;
  double scale = 0, sign_x = 0, sign_y = 0;
  bool swap = false;
  if (!ros::param::get(ns + "/lens_shift_scale", scale) ||
      !ros::param::get(ns + "/lens_shift_swap_xy", swap) ||
      !ros::param::get(ns + "/lens_shift_sign_x", sign_x) ||
      !ros::param::get(ns + "/lens_shift_sign_y", sign_y) ||
      !ros::param::get(ns + "/lens_shift_time_offset", c.time_offset_s)) {
    return ::testing::AssertionFailure() << "the .test file must set the lens_shift_* convention";
  }
  Eigen::Matrix2d P =
      swap ? (Eigen::Matrix2d() << 0, 1, 1, 0).finished() : Eigen::Matrix2d::Identity();
  P.row(0) *= sign_x;
  P.row(1) *= sign_y;
  c.matrix = scale * P;
  return ::testing::AssertionSuccess();
}

// WARN lines of the nodelet's manager that say a pair fell back for want of the lens log.
class RosoutCounter {
 public:
  RosoutCounter() {
    sub_ = ros::NodeHandle().subscribe("/rosout", 1000, &RosoutCounter::callback, this);
  }
  int count() {
    std::lock_guard<std::mutex> lock(mutex_);
    return count_;
  }
  std::string lines() {
    std::lock_guard<std::mutex> lock(mutex_);
    return lines_;
  }

 private:
  void callback(const rosgraph_msgs::LogConstPtr& log) {
    if (log->level != rosgraph_msgs::Log::WARN ||
        log->msg.find("lens-shift log") == std::string::npos ||
        log->msg.find("does not cover") == std::string::npos) {
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    ++count_;
    lines_ += log->msg + "\n";
  }
  ros::Subscriber sub_;
  std::mutex mutex_;
  int count_ = 0;
  std::string lines_;
};

TEST(GyroFlowLensLog, KnownTrajectoryReproducedAndGapsFallBackPerPair) {
  RollingShutterTiming timing;
  ASSERT_TRUE(readTiming(timing));
  int grid_width_px = 0, grid_height_px = 0;
  ASSERT_TRUE(readGridSize(grid_width_px, grid_height_px));
  Convention convention;
  ASSERT_TRUE(readConvention(convention));
  double max_gap_s = 0.0;
  ASSERT_TRUE(ros::param::get(std::string(kNodeletNamespace) + "/lens_shift_max_gap", max_gap_s));

  const Eigen::Matrix3d R_cam_imu = syntheticImuToCamera();
  const Eigen::Matrix3d K = syntheticK();
  LinearRateMotion motion;
  motion.reference_stamp = ros::Time(1000, 0);

  std::vector<StreamEvent> events;
  std::vector<ros::Time> frame_stamps;
  for (int j = 0; j < kFrameCount; ++j) {
    frame_stamps.push_back(motion.reference_stamp + ros::Duration(0.1 + j * kFramePeriodS));
  }
  const double end_tau_s = motion.tau(frame_stamps.back()) + 0.1;
  appendImuEvents(motion, R_cam_imu, end_tau_s, kImuLeadS, events);
  // Two gaps, starting 10 ms into the readout of frames 20 and 25 (camera clock).
  std::vector<std::pair<double, double>> gaps;
  for (int j : {20, 25})
    gaps.emplace_back(motion.tau(frame_stamps[j]) + 0.01,
                      motion.tau(frame_stamps[j]) + 0.01 + kGapS);
  std::vector<double> logged_taus;  // camera clock
  const Eigen::Matrix2d to_logged = convention.matrix.inverse();
  for (int k = 0; k * kLensPeriodS <= end_tau_s; ++k) {
    const double tau = k * kLensPeriodS;
    bool lost = false;
    for (const auto& [begin, end] : gaps) lost = lost || (tau >= begin && tau < end);
    if (lost) continue;
    logged_taus.push_back(tau);
    auto sample = boost::make_shared<LensShiftSample>();
    // The log's clock is the camera's minus the offset the nodelet adds back.
    sample->header.stamp = motion.reference_stamp + ros::Duration(tau - convention.time_offset_s);
    sample->header.frame_id = kCameraFrame;
    const Eigen::Vector2d logged = to_logged * trueShift(tau);
    sample->x = logged.x();
    sample->y = logged.y();
    sample->covariance = {-1.0, 0.0, 0.0, 0.0};
    StreamEvent event;
    event.publish_key_s = tau + kLensLatencyS;
    event.lens = sample;
    events.push_back(event);
  }
  appendFrameEvents(motion, frame_stamps, events);
  sortByPublishKey(events);

  RosoutCounter warnings;
  GyroFlowHarness harness(/*subscribe_color=*/false);
  harness.publishStaticTransform(R_cam_imu);
  ASSERT_TRUE(harness.waitForNodelet(30.0));
  const ros::WallTime lens_deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (harness.lensShiftSubscribers() == 0 && ros::WallTime::now() < lens_deadline)
    ros::WallDuration(0.05).sleep();
  ASSERT_GT(harness.lensShiftSubscribers(), 0u)
      << "the nodelet does not subscribe " << kLensShiftTopic;
  harness.play(events, kPlaybackSpeed);

  const ros::Time last_stamp = frame_stamps.back();
  EXPECT_TRUE(harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == last_stamp;
      },
      10.0))
      << "no GyroFlow for the last frame " << last_stamp;
  ros::WallDuration(1.0).sleep();  // the warning travels through /rosout

  // A pair is covered unless the samples around a gap (the last before it, the first after it)
  // bracket part of the interval it needs, from patch 0 of frame a to the last patch of frame b.
  auto covered = [&](double t0, double t1) {
    for (std::size_t k = 0; k + 1 < logged_taus.size(); ++k) {
      if (logged_taus[k + 1] - logged_taus[k] > max_gap_s && logged_taus[k + 1] > t0 &&
          logged_taus[k] < t1)
        return false;
    }
    return true;
  };
  std::map<ros::Time, int> index_of;
  for (int j = 0; j < kFrameCount; ++j) index_of[frame_stamps[j]] = j;
  int with_log = 0, fallbacks = 0;
  double worst_px = 0.0;
  std::map<int, bool> seen;
  for (const GyroFlowConstPtr& msg : harness.flows()) {
    SCOPED_TRACE("GyroFlow stamped " + std::to_string(msg->header.stamp.toSec()));
    ASSERT_EQ(index_of.count(msg->header.stamp), 1u);
    const int j = index_of[msg->header.stamp];
    ASSERT_GE(j, 1);
    EXPECT_FALSE(seen[j]) << "published twice";
    seen[j] = true;
    const ros::Time stamp_a = frame_stamps[j - 1], stamp_b = frame_stamps[j];
    EXPECT_TRUE(
        metadataAndFlowMatch(*msg, stamp_a, timing, K, R_cam_imu, grid_width_px, grid_height_px));
    const double interval_s = (stamp_b - stamp_a).toSec();
    // Patch capture times on the camera clock: the IMU patch time minus the camera-to-IMU offset.
    std::vector<Eigen::Matrix3d> gyro_only, with_lens;
    for (int i = 0; i < timing.patch_count; ++i) {
      const double tau_a_imu = timing.patchTau(motion, stamp_a, i);
      const Eigen::Matrix3d R =
          motion.cameraRotationChange(tau_a_imu, tau_a_imu + interval_s).transpose();
      const double tau_a = tau_a_imu - timing.time_offset_s, tau_b = tau_a + interval_s;
      Eigen::Matrix3d K_a = K, K_b = K;
      K_a.block<2, 1>(0, 2) += trueShift(tau_a);
      K_b.block<2, 1>(0, 2) += trueShift(tau_b);
      const Eigen::Matrix3d H_gyro = K * R * K.inverse(), H_lens = K_b * R * K_a.inverse();
      gyro_only.push_back(H_gyro / H_gyro(2, 2));
      with_lens.push_back(H_lens / H_lens(2, 2));
    }
    const double t0 = timing.patchTau(motion, stamp_a, 0) - timing.time_offset_s;
    const double t1 =
        timing.patchTau(motion, stamp_b, timing.patch_count - 1) - timing.time_offset_s;
    const std::vector<Eigen::Matrix3d> actual = homographiesOf(*msg);
    if (covered(t0, t1)) {
      ++with_log;
      EXPECT_EQ(msg->motion_model, GyroFlow::MOTION_GYRO_LENS_LOG);
      EXPECT_TRUE(homographiesMatch(with_lens, actual, 1e-4, 0.01));
      // The test can tell the lens apart: the gyro alone is pixels away.
      EXPECT_FALSE(homographiesMatch(gyro_only, actual, 1e-4, 0.01));
      for (std::size_t i = 0; i < actual.size() && i < with_lens.size(); ++i) {
        worst_px = std::max(worst_px, homographyError(with_lens[i], actual[i]).pixel_px);
      }
    } else {
      ++fallbacks;
      EXPECT_EQ(msg->motion_model, GyroFlow::MOTION_GYRO);
      EXPECT_TRUE(homographiesMatch(gyro_only, actual, 1e-6, 0.01));
    }
  }
  // Every pair after the first (which may be lost while connections settle) is published.
  for (int j = 2; j < kFrameCount; ++j) EXPECT_TRUE(seen[j]) << "no GyroFlow for frame " << j;
  EXPECT_GE(fallbacks, 3) << "both gaps must make pairs fall back";
  EXPECT_GE(with_log, kFrameCount - 10);
  // Both gaps fall within one throttle period (2 s) of playback: one warning says it.
  EXPECT_EQ(warnings.count(), 1) << warnings.lines();
  std::cout << "[ INFO     ] " << with_log << " pairs with the lens log (worst corner error "
            << worst_px << " px), " << fallbacks << " fell back to the gyro alone, "
            << warnings.count() << " warning(s):\n"
            << warnings.lines();
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::rostest_helpers::runRostestGtests(argc, argv, "test_gyro_flow_lens_log");
}
