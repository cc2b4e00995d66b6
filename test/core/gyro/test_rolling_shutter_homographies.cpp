#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

using test::applyHomography;
using test::phoneLikeK;
using test::sampledBuffer;

constexpr double kFramePeriod = 1.0 / 30.0;

RollingShutterConfig globalShutter(int patches) {
  RollingShutterConfig config;
  config.patch_count = patches;
  config.readout_time_s = 0.0;
  return config;
}

TEST(RollingShutterHomographies, RollAboutOpticalAxisRotatesAboutPrincipalPoint) {
  const double w = 0.9;  // rad/s about the optical axis (camera z)
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 1.0, 400.0, [&](double) { return Eigen::Vector3d(0, 0, w); });
  const Eigen::Matrix3d K = phoneLikeK();
  const auto result = computeRollingShutterHomographies(buffer, IntegrationOptions{},
                                                        globalShutter(6), K, 0.4, 0.4 + kFramePeriod);
  ASSERT_TRUE(result.ok()) << result.reason;
  const double theta = w * kFramePeriod;
  const Eigen::Vector2d principal(K(0, 2), K(1, 2));
  for (const Eigen::Matrix3d& H : result.homographies) {
    EXPECT_MATRIX_NEAR(principal, applyHomography(H, principal), 1e-9);
    // The camera turns by +theta about z, so the scene turns by -theta about the principal point.
    const double r = 100.0;
    const Eigen::Vector2d expected = principal + r * Eigen::Vector2d(std::cos(theta), -std::sin(theta));
    EXPECT_MATRIX_NEAR(expected, applyHomography(H, principal + Eigen::Vector2d(r, 0)), 1e-9);
  }
}

TEST(RollingShutterHomographies, SmallYawMovesCentreByFocalTimesTangent) {
  const double w = 0.35;  // rad/s about camera y (down): the camera pans right
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 1.0, 400.0, [&](double) { return Eigen::Vector3d(0, w, 0); });
  const Eigen::Matrix3d K = phoneLikeK();
  const auto result = computeRollingShutterHomographies(buffer, IntegrationOptions{},
                                                        globalShutter(1), K, 0.2, 0.2 + kFramePeriod);
  ASSERT_TRUE(result.ok()) << result.reason;
  const Eigen::Vector2d principal(K(0, 2), K(1, 2));
  const double theta = w * kFramePeriod;
  // Panning right moves the scene left.
  EXPECT_MATRIX_NEAR(Eigen::Vector2d(K(0, 2) - K(0, 0) * std::tan(theta), K(1, 2)),
                     applyHomography(result.homographies[0], principal), 1e-9);
}

TEST(RollingShutterHomographies, ReadoutTimeShiftsEachPatchAsPredicted) {
  // Yaw rate growing linearly, w(t) = alpha t: patch i sees angle alpha*T*(t_a(i) + T/2).
  const double alpha = 3.0;  // rad/s^2
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 1.0, 400.0, [&](double t) { return Eigen::Vector3d(0, alpha * t, 0); });
  const Eigen::Matrix3d K = phoneLikeK();
  for (auto reference : {PatchTimeReference::kPatchStart, PatchTimeReference::kPatchCentre}) {
    RollingShutterConfig config;
    config.patch_count = 6;
    config.readout_time_s = 0.022;
    config.time_offset_s = 0.004;
    config.patch_time = reference;
    const double stamp_a = 0.3, stamp_b = stamp_a + kFramePeriod;
    const auto result =
        computeRollingShutterHomographies(buffer, IntegrationOptions{}, config, K, stamp_a, stamp_b);
    ASSERT_TRUE(result.ok()) << result.reason;
    ASSERT_EQ(result.homographies.size(), 6u);
    const Eigen::Vector2d principal(K(0, 2), K(1, 2));
    double previous_shift = 0.0;
    for (int i = 0; i < 6; ++i) {
      const double fraction = reference == PatchTimeReference::kPatchCentre ? (i + 0.5) / 6 : i / 6.0;
      const double t_a = stamp_a + 0.004 + 0.022 * fraction;
      EXPECT_DOUBLE_EQ(t_a, patchImuTime(config, stamp_a, i));
      const double theta = alpha * kFramePeriod * (t_a + kFramePeriod / 2);
      const Eigen::Vector2d moved = applyHomography(result.homographies[i], principal);
      EXPECT_NEAR(K(0, 2) - K(0, 0) * std::tan(theta), moved.x(), 1e-9) << "patch " << i;
      // Later patches see a faster camera: their shift grows monotonically.
      const double shift = K(0, 2) - moved.x();
      if (i > 0) {
        EXPECT_GT(shift, previous_shift + 0.01);
      }
      previous_shift = shift;
    }
  }
}

TEST(RollingShutterHomographies, ZeroReadoutOrOnePatchDegeneratesToGlobalHomography) {
  auto rate = [](double t) { return Eigen::Vector3d(0.3 * std::sin(4 * t), 0.5 * t, -0.2); };
  const ImuSampleBuffer buffer = sampledBuffer(0.0, 1.0, 400.0, rate);
  const Eigen::Matrix3d K = phoneLikeK();
  const double stamp_a = 0.25, stamp_b = stamp_a + kFramePeriod;
  const IntegrationResult global = integrateRotation(buffer, stamp_a, stamp_b, IntegrationOptions{});
  ASSERT_TRUE(global.ok());
  const Eigen::Matrix3d H_global = rotationHomography(K, global.rotation.transpose());

  const auto zero_readout =
      computeRollingShutterHomographies(buffer, IntegrationOptions{}, globalShutter(6), K, stamp_a, stamp_b);
  ASSERT_TRUE(zero_readout.ok());
  for (const auto& H : zero_readout.homographies) EXPECT_MATRIX_NEAR(H_global, H, 1e-12);

  RollingShutterConfig one_patch;
  one_patch.patch_count = 1;
  one_patch.readout_time_s = 0.03;
  one_patch.patch_time = PatchTimeReference::kPatchStart;
  const auto single =
      computeRollingShutterHomographies(buffer, IntegrationOptions{}, one_patch, K, stamp_a, stamp_b);
  ASSERT_TRUE(single.ok());
  ASSERT_EQ(single.homographies.size(), 1u);
  EXPECT_MATRIX_NEAR(H_global, single.homographies[0], 1e-12);
}

TEST(RollingShutterHomographies, RotatesGyroIntoCameraFrameAndAppliesTimeOffset) {
  // IMU x axis = camera y axis (a phone-like mount); a proper rotation: camera = R * imu.
  Eigen::Matrix3d R_cam_imu;
  R_cam_imu << 0, -1, 0,  //
      1, 0, 0,            //
      0, 0, 1;
  const double w = 0.35, offset = 0.0125;  // a whole number of 400 Hz samples
  // IMU clock = camera clock + offset; the camera starts turning exactly at frame a (IMU time
  // 0.2 + offset, a sample stamp), so an ignored offset would miss 12.5 ms of motion.
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 1.0, 400.0, [&](double t) { return Eigen::Vector3d(t > 0.2 + offset - 0.001 ? w : 0.0, 0, 0); });
  RollingShutterConfig config = globalShutter(1);
  config.imu_to_camera_rotation = R_cam_imu;
  config.time_offset_s = offset;
  const Eigen::Matrix3d K = phoneLikeK();
  IntegrationOptions zoh;
  zoh.interpolation = RateInterpolation::kZeroOrderHold;
  const auto result = computeRollingShutterHomographies(buffer, zoh, config, K, 0.2, 0.2 + kFramePeriod);
  ASSERT_TRUE(result.ok());
  // IMU +x = camera +y: the camera pans right by w*T, the centre moves left.
  const Eigen::Vector2d moved = applyHomography(result.homographies[0], Eigen::Vector2d(K(0, 2), K(1, 2)));
  EXPECT_NEAR(K(0, 2) - K(0, 0) * std::tan(w * kFramePeriod), moved.x(), 1e-6);
  EXPECT_NEAR(K(1, 2), moved.y(), 1e-9);
}

TEST(RollingShutterHomographies, ReportsMissingImuData) {
  const ImuSampleBuffer buffer =
      sampledBuffer(0.0, 0.3, 400.0, [](double) { return Eigen::Vector3d(0, 0.1, 0); });
  RollingShutterConfig config;
  config.readout_time_s = 0.02;
  const auto result = computeRollingShutterHomographies(buffer, IntegrationOptions{}, config,
                                                        phoneLikeK(), 0.28, 0.28 + kFramePeriod);
  EXPECT_EQ(result.status, IntegrationStatus::kNotYetAvailable);
  EXPECT_TRUE(result.homographies.empty());
  EXPECT_FALSE(result.reason.empty());
}

TEST(RollingShutterConfig, ValidatesFields) {
  RollingShutterConfig config;
  EXPECT_EQ(config.validate(), "");
  config.patch_count = 0;
  EXPECT_NE(config.validate().find("patch_count"), std::string::npos);
  config = RollingShutterConfig{};
  config.readout_time_s = -0.01;
  EXPECT_NE(config.validate().find("readout_time"), std::string::npos);
  config = RollingShutterConfig{};
  config.imu_to_camera_rotation = -Eigen::Matrix3d::Identity();  // improper: det -1
  EXPECT_NE(config.validate().find("proper rotation"), std::string::npos);
}

TEST(PatchIndexOfRow, SplitsRowsEvenly) {
  EXPECT_EQ(patchIndexOfRow(0, 600, 10), 0);
  EXPECT_EQ(patchIndexOfRow(59, 600, 10), 0);
  EXPECT_EQ(patchIndexOfRow(60, 600, 10), 1);
  EXPECT_EQ(patchIndexOfRow(599, 600, 10), 9);
  EXPECT_EQ(patchIndexOfRow(-3, 600, 10), 0);
  EXPECT_EQ(patchIndexOfRow(700, 600, 10), 9);
}

}  // namespace
}  // namespace deep_ois
