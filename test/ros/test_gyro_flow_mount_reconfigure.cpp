// ~online_calibration_mount: the mount the online calibration publishes (OnlineCalibration's
// row-major R_cam_imu) reaches the gyro flow as its r_cam_imu reconfigure value and comes back
// from it as the same rotation (the path GyroFlowRos::onlineCalibrationCallback takes through
// GyroFlowReconfigure::set).
#include <gtest/gtest.h>

#include <Eigen/Core>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/ros/live/gyro_flow_reconfigure.h"

namespace deep_ois {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

OnlineCalibration messageWith(const Eigen::Matrix3d& R_cam_imu, bool mount_estimated) {
  OnlineCalibration msg;
  msg.time_offset = 0.023;
  msg.readout_time = 0.021;
  msg.gyro_bias = {0.004, -0.003, 0.002};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) msg.imu_to_camera_rotation[static_cast<std::size_t>(3 * r + c)] = R_cam_imu(r, c);
  msg.mount_estimated = mount_estimated;
  return msg;
}

// The gyro flow following the tf (no ~imu_to_camera_rotation), identity as its fallback.
GyroFlowParameters followingTf() {
  GyroFlowParameters params;
  params.rotation_from_tf = true;
  params.rolling_shutter.imu_to_camera_rotation = Eigen::Matrix3d::Identity();
  return params;
}

// Message -> the parameters GyroFlowReconfigure::set is given -> its config -> the parameters
// the server's callback applies (from the tf-following start, as a fresh nodelet).
GyroFlowParameters throughReconfigure(const OnlineCalibration& msg, GyroFlowConfig* config_out = nullptr) {
  GyroFlowParameters wanted = followingTf();
  applyOnlineCalibration(msg, wanted);
  const GyroFlowConfig config = toGyroFlowConfig(wanted);
  if (config_out) *config_out = config;
  GyroFlowParameters applied = followingTf();
  EXPECT_EQ(applyGyroFlowConfig(config, applied), "");
  return applied;
}

TEST(GyroFlowMountReconfigure, AKnownPermutationBecomesItsRowMajorText) {
  // IMU y is camera x, IMU z is camera -y, IMU x is camera -z (a phone IMU on its side).
  Eigen::Matrix3d R;
  R << 0, 1, 0,  //
      0, 0, -1,  //
      -1, 0, 0;
  ASSERT_TRUE(isProperRotation(R));
  GyroFlowConfig config;
  const GyroFlowParameters applied = throughReconfigure(messageWith(R, true), &config);
  EXPECT_EQ(config.r_cam_imu, "0 1 0 0 0 -1 -1 0 0");
  EXPECT_FALSE(applied.rotation_from_tf);
  EXPECT_EQ(applied.rolling_shutter.imu_to_camera_rotation, R);
  // A turn about the IMU's x axis is one about the camera's -z axis (the transpose would say +y).
  const Eigen::Vector3d camera_rate = applied.rolling_shutter.imu_to_camera_rotation * Eigen::Vector3d(1.0, 0.0, 0.0);
  EXPECT_EQ(camera_rate, Eigen::Vector3d(0.0, 0.0, -1.0));
  EXPECT_DOUBLE_EQ(applied.rolling_shutter.time_offset_s, 0.023);
  EXPECT_DOUBLE_EQ(applied.rolling_shutter.readout_time_s, 0.021);
  EXPECT_EQ(applied.integration.gyro_bias_rad_s, Eigen::Vector3d(0.004, -0.003, 0.002));
}

TEST(GyroFlowMountReconfigure, EveryPermutationWithASmallRotationRoundTrips) {
  const std::vector<Eigen::Matrix3d>& permutations = signedAxisPermutations();
  ASSERT_EQ(permutations.size(), 24u);
  for (std::size_t i = 0; i < permutations.size(); ++i) {
    // The estimate: a permutation and a few degrees about it (as OnlineCalibrationEstimator's).
    const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(1.5, -2.0, 1.0) * kDeg) * permutations[i];
    const GyroFlowParameters applied = throughReconfigure(messageWith(R, true));
    EXPECT_FALSE(applied.rotation_from_tf);
    EXPECT_LT((applied.rolling_shutter.imu_to_camera_rotation - R).cwiseAbs().maxCoeff(), 1e-11) << "permutation " << i;
    EXPECT_EQ(nearestSignedAxisPermutation(applied.rolling_shutter.imu_to_camera_rotation), static_cast<int>(i));
  }
}

TEST(GyroFlowMountReconfigure, AHeldMountKeepsFollowingTheTf) {
  // ~online_calibration_mount false: the message's rotation is the start's, not pushed.
  GyroFlowConfig config;
  const GyroFlowParameters applied = throughReconfigure(messageWith(signedAxisPermutations()[13], false), &config);
  EXPECT_EQ(config.r_cam_imu, "");
  EXPECT_TRUE(applied.rotation_from_tf);
  EXPECT_EQ(applied.rolling_shutter.imu_to_camera_rotation, Eigen::Matrix3d::Identity());
  EXPECT_DOUBLE_EQ(applied.rolling_shutter.time_offset_s, 0.023);
}

TEST(GyroFlowMountReconfigure, AReflectionIsRefusedNamingTheParameter) {
  Eigen::Matrix3d mirror = Eigen::Matrix3d::Identity();
  mirror(2, 2) = -1.0;
  GyroFlowParameters wanted = followingTf();
  applyOnlineCalibration(messageWith(mirror, true), wanted);
  GyroFlowParameters applied = followingTf();
  const std::string problem = applyGyroFlowConfig(toGyroFlowConfig(wanted), applied);
  EXPECT_NE(problem.find("r_cam_imu is not a rotation"), std::string::npos) << problem;
  EXPECT_TRUE(applied.rotation_from_tf);  // unchanged
}

}  // namespace
}  // namespace deep_ois
