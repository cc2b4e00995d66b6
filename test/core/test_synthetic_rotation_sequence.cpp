#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "deep_ois/core/orientation_integrator.h"
#include "deep_ois/core/rolling_shutter_homographies.h"
#include "deep_ois/core/synthetic_rotation_sequence.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

using test::applyHomography;

// Short sequences keep the tests fast; the renderer and motion are the same as at full length.
SyntheticSequenceConfig shortConfig(std::uint32_t seed) {
  SyntheticSequenceConfig config;
  config.seed = seed;
  config.duration_s = 0.5;
  return config;
}

double meanAbsDifference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar mean = cv::mean(diff);
  return (mean[0] + mean[1] + mean[2]) / 3.0;
}

// Pixel of a direction `ray_cam` (camera frame) through an undistorted pinhole K.
Eigen::Vector2d project(const Eigen::Matrix3d& K, const Eigen::Vector3d& ray_cam) {
  return (K * ray_cam).hnormalized();
}

TEST(SyntheticRotationSequence, ValidateNamesTheBadField) {
  SyntheticSequenceConfig config;
  EXPECT_EQ("", config.validate());

  config.width_px = 4;
  EXPECT_NE(std::string::npos, config.validate().find("width_px"));
  config = SyntheticSequenceConfig();
  config.readout_time_s = 0.05;  // longer than the 33 ms frame period
  EXPECT_NE(std::string::npos, config.validate().find("readout_time_s"));
  config = SyntheticSequenceConfig();
  config.imu_to_camera_rotation(2, 2) = 1.0;  // a reflection
  EXPECT_NE(std::string::npos, config.validate().find("imu_to_camera_rotation"));
  config = SyntheticSequenceConfig();
  config.duration_s = 0.04;  // a single frame
  EXPECT_NE(std::string::npos, config.validate().find("duration_s"));
  EXPECT_THROW(SyntheticRotationSequence{config}, std::invalid_argument);
}

TEST(SyntheticRotationSequence, CameraMatchesTheFieldOfView) {
  const SyntheticRotationSequence sequence(shortConfig(1));
  const CameraModel& camera = sequence.camera();
  EXPECT_EQ(360, camera.width());
  EXPECT_EQ(270, camera.height());
  EXPECT_FALSE(camera.hasDistortion());
  // The left and right image edges (pixel -0.5 and w - 0.5) are 35 degrees off axis.
  const double half_fov = std::atan((camera.width() - 0.5 - camera.K()(0, 2)) / camera.K()(0, 0));
  EXPECT_NEAR(35.0, half_fov * 180.0 / M_PI, 1e-9);
  EXPECT_EQ(15, sequence.frameCount());
}

TEST(SyntheticRotationSequence, SameSeedIsIdenticalAndOtherSeedDiffers) {
  const SyntheticRotationSequence first(shortConfig(5));
  const SyntheticRotationSequence again(shortConfig(5));
  const SyntheticRotationSequence other(shortConfig(6));

  ASSERT_EQ(first.imuSamples().size(), again.imuSamples().size());
  ASSERT_EQ(first.imuSamples().size(), other.imuSamples().size());
  double other_rate_difference = 0.0;
  for (std::size_t k = 0; k < first.imuSamples().size(); ++k) {
    const ImuSample& a = first.imuSamples()[k];
    EXPECT_EQ(a.stamp_s, again.imuSamples()[k].stamp_s);
    EXPECT_TRUE(a.angular_velocity_rad_s == again.imuSamples()[k].angular_velocity_rad_s);
    other_rate_difference =
        std::max(other_rate_difference,
                 (a.angular_velocity_rad_s - other.imuSamples()[k].angular_velocity_rad_s).norm());
  }
  EXPECT_GT(other_rate_difference, 0.05);

  for (int frame : {0, first.frameCount() - 1}) {
    cv::Mat a, b, c;
    first.renderFrame(frame, a);
    again.renderFrame(frame, b);
    other.renderFrame(frame, c);
    EXPECT_EQ(0.0, cv::norm(a, b, cv::NORM_INF)) << "frame " << frame;
    EXPECT_GT(meanAbsDifference(a, c), 15.0) << "frame " << frame;
  }
}

TEST(SyntheticRotationSequence, ImuSamplesAreTheTrueRatesInTheImuFrame) {
  SyntheticSequenceConfig config = shortConfig(3);
  config.time_offset_s = 0.004;
  const SyntheticRotationSequence sequence(config);
  const std::vector<ImuSample>& samples = sequence.imuSamples();
  const Eigen::Matrix3d R_imu_cam = config.imu_to_camera_rotation.transpose();

  // The stream covers every frame (IMU clock) with the margin on both sides.
  const double last_row_s = sequence.rowTime(sequence.frameCount() - 1, config.height_px);
  EXPECT_LE(samples.front().stamp_s, config.time_offset_s - config.imu_margin_s + 1e-12);
  EXPECT_GE(samples.back().stamp_s, config.time_offset_s + last_row_s + config.imu_margin_s);
  double peak_rate = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (k > 0) {
      EXPECT_NEAR(1.0 / config.imu_rate_hz, samples[k].stamp_s - samples[k - 1].stamp_s, 1e-12);
    }
    const Eigen::Vector3d expected =
        R_imu_cam * sequence.angularVelocityCamera(samples[k].stamp_s - config.time_offset_s);
    EXPECT_MATRIX_NEAR(expected, samples[k].angular_velocity_rad_s, 1e-12);
    peak_rate = std::max(peak_rate, samples[k].angular_velocity_rad_s.cwiseAbs().maxCoeff());
  }
  // Hand-held-like: clearly moving, yet below ~0.5 rad/s shake plus the pan.
  EXPECT_GT(peak_rate, 0.1);
  EXPECT_LT(peak_rate, config.shake_rate_rad_s + config.pan_rate_rad_s + 1e-9);
}

TEST(SyntheticRotationSequence, OrientationFollowsTheAngularVelocity) {
  const SyntheticRotationSequence sequence(shortConfig(4));
  // World frame as documented: at t = 0 the optical axis is world x, image down is world -z.
  Eigen::Matrix3d R_w_c0;
  R_w_c0 << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  EXPECT_MATRIX_NEAR(R_w_c0, sequence.orientation(0.0), 1e-12);
  // dR/dt = R [w]x: the body-frame rotation over a short step is w times the step.
  const double h = 1e-4;
  for (double t : {-0.05, 0.0123, 0.2, 0.41}) {
    const Eigen::Vector3d rotation_vector =
        logSO3(sequence.orientation(t).transpose() * sequence.orientation(t + h));
    EXPECT_MATRIX_NEAR(sequence.angularVelocityCamera(t + 0.5 * h) * h, rotation_vector, 1e-10);
    const Eigen::Matrix3d R = sequence.orientation(t);
    EXPECT_MATRIX_NEAR(Eigen::Matrix3d::Identity(), R * R.transpose(), 1e-12);
  }
}

TEST(SyntheticRotationSequence, GyroNoiseHasTheConfiguredSpread) {
  SyntheticSequenceConfig config = shortConfig(8);
  config.gyro_noise_std_rad_s = 0.01;
  const SyntheticRotationSequence sequence(config);
  const Eigen::Matrix3d R_imu_cam = config.imu_to_camera_rotation.transpose();
  double sum = 0.0, sum_squares = 0.0;
  int count = 0;
  for (const ImuSample& sample : sequence.imuSamples()) {
    const Eigen::Vector3d error =
        sample.angular_velocity_rad_s - R_imu_cam * sequence.angularVelocityCamera(sample.stamp_s);
    for (int axis = 0; axis < 3; ++axis, ++count) {
      sum += error[axis];
      sum_squares += error[axis] * error[axis];
    }
  }
  ASSERT_GT(count, 600);
  const double mean = sum / count;
  EXPECT_NEAR(0.0, mean, 4.0 * 0.01 / std::sqrt(count));
  EXPECT_NEAR(0.01, std::sqrt(sum_squares / count - mean * mean), 0.001);
}

// The IMU stream integrated by the core predicts, for every row patch, where the sequence's true
// per-row orientations put a far point: the whole chain (IMU frame, R_cam_imu, time offset,
// rolling-shutter row times) agrees between simulator and core.
TEST(SyntheticRotationSequence, GyroHomographiesPredictTheTruePerRowMotion) {
  SyntheticSequenceConfig config = shortConfig(11);
  config.time_offset_s = 0.004;
  const SyntheticRotationSequence sequence(config);
  const ImuSampleBuffer buffer = sequence.imuBuffer();
  const Eigen::Matrix3d K = sequence.camera().K();
  const int patches = 6;
  const RollingShutterConfig rolling = sequence.rollingShutterConfig(patches);
  RollingShutterConfig global = rolling;
  global.readout_time_s = 0.0;

  double worst_error = 0.0, worst_global_error = 0.0, largest_motion = 0.0;
  for (int a = 0; a + 1 < sequence.frameCount(); ++a) {
    const double stamp_a = sequence.frameStamp(a), stamp_b = sequence.frameStamp(a + 1);
    const auto result = computeRollingShutterHomographies(buffer, IntegrationOptions{}, rolling, K,
                                                          stamp_a, stamp_b);
    const auto ignoring_readout = computeRollingShutterHomographies(buffer, IntegrationOptions{},
                                                                    global, K, stamp_a, stamp_b);
    ASSERT_TRUE(result.ok()) << result.reason;
    ASSERT_TRUE(ignoring_readout.ok()) << ignoring_readout.reason;
    for (int i = 0; i < patches; ++i) {
      // kPatchCentre: the patch stands for its middle row.
      const double row = (i + 0.5) * config.height_px / patches;
      const double t_a = sequence.rowTime(a, row);
      const double t_b = t_a + (stamp_b - stamp_a);
      const Eigen::Matrix3d R_wc_a = sequence.orientation(t_a), R_wc_b = sequence.orientation(t_b);
      for (double x : {10.0, 179.5, 349.0}) {
        const Eigen::Vector2d p_a(x, row);
        const Eigen::Vector3d direction_world = R_wc_a * K.inverse() * p_a.homogeneous();
        const Eigen::Vector2d p_b = project(K, R_wc_b.transpose() * direction_world);
        worst_error =
            std::max(worst_error, (applyHomography(result.homographies[i], p_a) - p_b).norm());
        worst_global_error =
            std::max(worst_global_error,
                     (applyHomography(ignoring_readout.homographies[i], p_a) - p_b).norm());
        largest_motion = std::max(largest_motion, (p_b - p_a).norm());
      }
    }
  }
  EXPECT_LT(worst_error, 0.05);
  // The check has teeth: the motion is several pixels and ignoring the readout is visibly wrong.
  EXPECT_GT(largest_motion, 3.0);
  EXPECT_GT(worst_global_error, 0.5);
}

// With one sample per pixel, pixel (x, y) is exactly the environment along the ray through it at
// the row's own capture time; the frame stamp's orientation does not explain the lower rows.
void expectRowsRenderedAtTheirCaptureTime(const SyntheticSequenceConfig& config) {
  const SyntheticRotationSequence sequence(config);
  const CameraModel& camera = sequence.camera();
  // The frame that turns most during its readout shows the row timing best.
  int frame = 0;
  double largest_turn = 0.0;
  for (int k = 0; k < sequence.frameCount(); ++k) {
    const double turn = logSO3(sequence.orientation(sequence.rowTime(k, 0)).transpose() *
                               sequence.orientation(sequence.rowTime(k, config.height_px)))
                            .norm();
    if (turn > largest_turn) largest_turn = turn, frame = k;
  }
  cv::Mat rgb;
  sequence.renderFrame(frame, rgb);

  double worst_difference = 0.0, stamp_time_difference = 0.0;
  int stamp_time_count = 0;
  for (int y = 0; y < config.height_px; y += 7) {
    const Eigen::Matrix3d R_row = sequence.orientation(sequence.rowTime(frame, y));
    const Eigen::Matrix3d R_stamp = sequence.orientation(sequence.frameStamp(frame));
    for (int x = 0; x < config.width_px; x += 5) {
      const Eigen::Vector2d raw(x, y);
      const Eigen::Vector3d ray = camera.Kinv() * camera.undistort(raw).homogeneous();
      const cv::Vec3f expected = sequence.environmentColour(R_row * ray) * 255.0f;
      const cv::Vec3b rendered = rgb.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        worst_difference = std::max(worst_difference, std::abs(rendered[c] - double(expected[c])));
      }
      if (y > config.height_px / 2) {
        const cv::Vec3f at_stamp = sequence.environmentColour(R_stamp * ray) * 255.0f;
        for (int c = 0; c < 3; ++c) {
          stamp_time_difference += std::abs(rendered[c] - double(at_stamp[c]));
          ++stamp_time_count;
        }
      }
    }
  }
  EXPECT_LE(worst_difference, 0.5 + 1e-3);  // rounding to 8 bits only
  EXPECT_GT(stamp_time_difference / stamp_time_count, 2.0);
}

TEST(SyntheticRotationSequence, RowsAreRenderedAtTheirOwnCaptureTime) {
  SyntheticSequenceConfig config = shortConfig(21);
  config.supersampling = 1;
  expectRowsRenderedAtTheirCaptureTime(config);
}

TEST(SyntheticRotationSequence, DistortedRowsAreRenderedAtTheirOwnCaptureTime) {
  SyntheticSequenceConfig config = shortConfig(22);
  config.supersampling = 1;
  config.plumb_bob = {-0.12, 0.03, 0.0005, -0.0003, 0.0};
  expectRowsRenderedAtTheirCaptureTime(config);
}

// Pixel content: frame b sampled at the gyro homography's prediction reproduces frame a in a band
// around each patch's reference row, up to interpolation; unwarped, the frames differ clearly.
TEST(SyntheticRotationSequence, RenderedFramesFollowTheGyroHomography) {
  const SyntheticRotationSequence sequence(shortConfig(31));
  const ImuSampleBuffer buffer = sequence.imuBuffer();
  const Eigen::Matrix3d K = sequence.camera().K();
  const int patches = 6, width = sequence.camera().width(), height = sequence.camera().height();
  const RollingShutterConfig rolling = sequence.rollingShutterConfig(patches);

  // The frame pair with the largest image motion makes the clearest test.
  int best_a = 0;
  double best_motion = 0.0;
  for (int a = 0; a + 1 < sequence.frameCount(); ++a) {
    const auto result =
        computeRollingShutterHomographies(buffer, IntegrationOptions{}, rolling, K,
                                          sequence.frameStamp(a), sequence.frameStamp(a + 1));
    ASSERT_TRUE(result.ok()) << result.reason;
    const Eigen::Vector2d centre(K(0, 2), K(1, 2));
    const double motion =
        (applyHomography(result.homographies[patches / 2], centre) - centre).norm();
    if (motion > best_motion) best_motion = motion, best_a = a;
  }
  ASSERT_GT(best_motion, 3.0);

  cv::Mat frame_a, frame_b;
  sequence.renderFrame(best_a, frame_a);
  sequence.renderFrame(best_a + 1, frame_b);
  const auto result = computeRollingShutterHomographies(buffer, IntegrationOptions{}, rolling, K,
                                                        sequence.frameStamp(best_a),
                                                        sequence.frameStamp(best_a + 1));
  ASSERT_TRUE(result.ok()) << result.reason;
  for (int i = 0; i < patches; ++i) {
    cv::Mat H;
    cv::Mat(cv::Matx33d(result.homographies[i].data()).t()).copyTo(H);  // Eigen is column-major
    // warped(p) = b(H p): frame b brought back onto frame a's pixels.
    cv::Mat warped;
    cv::warpPerspective(frame_b, warped, H, frame_a.size(),
                        cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    // A band of rows around the patch's reference row, away from borders the motion uncovers.
    const int row = static_cast<int>((i + 0.5) * height / patches);
    const cv::Rect band(16, std::max(0, row - 3), width - 32, 7);
    const double aligned = meanAbsDifference(frame_a(band), warped(band));
    const double unaligned = meanAbsDifference(frame_a(band), frame_b(band));
    EXPECT_LT(aligned, 2.0) << "patch " << i;
    EXPECT_LT(aligned, 0.15 * unaligned) << "patch " << i;
  }
}

}  // namespace
}  // namespace deep_ois
