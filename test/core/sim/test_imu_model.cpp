#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "test_helpers.h"
#include "sim_test_helpers.h"

namespace deep_ois {
namespace sim {
namespace {

ImuConfig noiseless() {
  ImuConfig config;
  config.gyro_noise_density = 0.0;
  config.gyro_bias_random_walk = 0.0;
  config.gyro_initial_bias_rad_s = 0.0;
  config.accel_noise_density = 0.0;
  return config;
}

// Sample standard deviation per axis.
Eigen::Vector3d stddev(const std::vector<Eigen::Vector3d>& values) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), square = Eigen::Vector3d::Zero();
  for (const auto& v : values) mean += v;
  mean /= static_cast<double>(values.size());
  for (const auto& v : values) square += (v - mean).cwiseAbs2();
  return (square / static_cast<double>(values.size() - 1)).cwiseSqrt();
}

TEST(ImuModel, StampsOnTheImuClockWithTheOffsetApplied) {
  const CameraMotion motion(CameraMotionConfig(), 1, -0.25, 2.25);
  ImuConfig config = noiseless();
  config.time_offset_s = 0.0123;
  const double start = -0.1, end = 2.0;
  const auto samples = sampleImu(config, motion, 1, start, end);
  const double period = 1.0 / config.rate_hz;
  ASSERT_EQ(static_cast<std::size_t>(std::round((end - start) * config.rate_hz)), samples.size());
  EXPECT_GE(samples.front().stamp_s - config.time_offset_s, start - 1e-12);
  EXPECT_LT(samples.front().stamp_s - config.time_offset_s, start + period);
  EXPECT_LE(samples.back().stamp_s - config.time_offset_s, end + 1e-12);
  EXPECT_GT(samples.back().stamp_s - config.time_offset_s, end - period);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    // Ticks of the IMU's own clock.
    EXPECT_NEAR(samples[i].stamp_s * config.rate_hz,
                std::round(samples[i].stamp_s * config.rate_hz), 1e-9);
    if (i > 0) {
      EXPECT_NEAR(period, samples[i].stamp_s - samples[i - 1].stamp_s, 1e-12);
    }
    // The reading at IMU stamp s is the motion at camera time s - offset.
    const Eigen::Vector3d expected = config.imu_to_camera_rotation.transpose() *
                                     motion.angularVelocity(samples[i].stamp_s - 0.0123);
    EXPECT_MATRIX_NEAR(expected, samples[i].angular_velocity_rad_s, 1e-15);
  }
  // A different offset moves the sample instants against the motion, not just the labels.
  ImuConfig late = config;
  late.time_offset_s = 0.0;
  const auto unshifted = sampleImu(late, motion, 1, start, end);
  EXPECT_GT((unshifted[100].angular_velocity_rad_s - samples[100].angular_velocity_rad_s).norm(),
            1e-3);
}

TEST(ImuModel, RotatesIntoTheImuFrame) {
  const CameraMotion motion(CameraMotionConfig(), 2, 0.0, 1.0);
  ImuConfig config = noiseless();
  config.imu_to_camera_rotation =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()).toRotationMatrix();
  for (const auto& sample : sampleImu(config, motion, 1, 0.0, 1.0)) {
    EXPECT_MATRIX_NEAR(motion.angularVelocity(sample.stamp_s),
                       config.imu_to_camera_rotation * sample.angular_velocity_rad_s, 1e-14);
  }
}

TEST(ImuModel, StillCameraFeelsGravityUpwards) {
  const CameraMotion motion(test::stillMotionConfig(), 1, 0.0, 1.0);
  const auto samples = sampleImu(noiseless(), motion, 1, 0.0, 1.0);
  const Eigen::Matrix3d R_cam_imu = ImuConfig().imu_to_camera_rotation;
  for (const auto& sample : samples) {
    // Camera y points down, so the reaction to gravity reads along camera -y; with the default
    // phone mount (IMU x = camera y) that is IMU -x.
    EXPECT_MATRIX_NEAR(Eigen::Vector3d(0.0, -9.81, 0.0),
                       R_cam_imu * sample.linear_acceleration_m_s2, 1e-12);
    EXPECT_MATRIX_NEAR(Eigen::Vector3d(-9.81, 0.0, 0.0), sample.linear_acceleration_m_s2, 1e-12);
    EXPECT_EQ(Eigen::Vector3d::Zero(), sample.angular_velocity_rad_s);
  }
}

TEST(ImuModel, AccelerometerFollowsPoseAndMotion) {
  const CameraMotion motion(CameraMotionConfig(), 3, 0.0, 2.0);
  const ImuConfig config = noiseless();
  for (const auto& sample : sampleImu(config, motion, 1, 0.0, 2.0)) {
    // Back to the world: R_world_cam R_cam_imu f + g = a.
    const Eigen::Vector3d a_world = motion.pose(sample.stamp_s).R_world_cam *
                                        config.imu_to_camera_rotation *
                                        sample.linear_acceleration_m_s2 +
                                    Eigen::Vector3d(0.0, 0.0, -9.81);
    EXPECT_MATRIX_NEAR(motion.linearAcceleration(sample.stamp_s), a_world, 1e-12);
  }
}

TEST(ImuModel, WhiteNoiseSigmas) {
  const CameraMotion motion(test::stillMotionConfig(), 1, 0.0, 20.0);
  ImuConfig config = noiseless();
  config.gyro_noise_density = 1e-3;
  config.accel_noise_density = 4e-3;
  const auto samples = sampleImu(config, motion, 9, 0.0, 20.0);
  std::vector<Eigen::Vector3d> gyro, accel;
  for (const auto& s : samples) {
    gyro.push_back(s.angular_velocity_rad_s);
    accel.push_back(s.linear_acceleration_m_s2);
  }
  const double scale = std::sqrt(config.rate_hz / 2.0);
  const Eigen::Vector3d gyro_sigma = stddev(gyro), accel_sigma = stddev(accel);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(config.gyro_noise_density * scale, gyro_sigma[axis],
                0.1 * config.gyro_noise_density * scale);
    EXPECT_NEAR(config.accel_noise_density * scale, accel_sigma[axis],
                0.1 * config.accel_noise_density * scale);
  }
  std::printf("[ figures  ] gyro noise sigma %.5f %.5f %.5f rad/s (expected %.5f)\n",
              gyro_sigma.x(), gyro_sigma.y(), gyro_sigma.z(), config.gyro_noise_density * scale);
}

TEST(ImuModel, BiasRandomWalkGrowsWithTime) {
  CameraMotionConfig slow = test::stillMotionConfig();  // a long span: a coarse orientation grid is enough
  slow.integration_rate_hz = 200.0;
  const CameraMotion motion(slow, 1, 0.0, 400.0);
  ImuConfig config = noiseless();
  config.gyro_bias_random_walk = 1e-3;
  const auto samples = sampleImu(config, motion, 4, 0.0, 400.0);
  // The measurement carries exactly the reported bias.
  for (std::size_t i = 0; i < samples.size(); i += 997) {
    const Eigen::Vector3d truth =
        config.imu_to_camera_rotation.transpose() * motion.angularVelocity(samples[i].stamp_s);
    EXPECT_MATRIX_NEAR(truth + samples[i].true_bias_rad_s, samples[i].angular_velocity_rad_s,
                       1e-15);
  }
  EXPECT_EQ(Eigen::Vector3d::Zero(), samples.front().true_bias_rad_s);
  // Increments over non-overlapping windows: variance = random_walk^2 * window.
  for (double window_s : {1.0, 4.0}) {
    const std::size_t lag = static_cast<std::size_t>(window_s * config.rate_hz);
    double sum = 0.0;
    int count = 0;
    for (std::size_t i = 0; i + lag < samples.size(); i += lag) {
      sum += (samples[i + lag].true_bias_rad_s - samples[i].true_bias_rad_s).squaredNorm();
      count += 3;
    }
    const double sigma = std::sqrt(sum / count);
    const double expected = config.gyro_bias_random_walk * std::sqrt(window_s);
    EXPECT_NEAR(expected, sigma, 0.15 * expected) << window_s << " s";
    std::printf("[ figures  ] bias change over %.0f s: sigma %.2e (expected %.2e)\n", window_s,
                sigma, expected);
  }
}

TEST(ImuModel, InitialBiasSpread) {
  const CameraMotion motion(test::stillMotionConfig(), 1, 0.0, 0.01);
  ImuConfig config = noiseless();
  config.gyro_initial_bias_rad_s = 0.002;
  std::vector<Eigen::Vector3d> biases;
  for (std::uint32_t seed = 0; seed < 300; ++seed) {
    biases.push_back(sampleImu(config, motion, seed, 0.0, 0.01).front().true_bias_rad_s);
  }
  const Eigen::Vector3d spread = stddev(biases);
  for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(0.002, spread[axis], 0.0003);
}

// A known initial bias (for calibration benchmarks) replaces the random draw and leaves every
// other random stream as it was.
TEST(ImuModel, FixedInitialBiasVector) {
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 0.5);
  ImuConfig config;
  const auto random = sampleImu(config, motion, 5, 0.0, 0.5);
  config.gyro_initial_bias_vector_rad_s = Eigen::Vector3d(0.004, -0.006, 0.001);
  const auto fixed = sampleImu(config, motion, 5, 0.0, 0.5);
  ASSERT_EQ(random.size(), fixed.size());
  EXPECT_EQ(fixed.front().true_bias_rad_s, *config.gyro_initial_bias_vector_rad_s);
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    // Same noise and the same random walk, only the starting bias differs.
    const Eigen::Vector3d shift = *config.gyro_initial_bias_vector_rad_s - random.front().true_bias_rad_s;
    EXPECT_MATRIX_NEAR(random[i].angular_velocity_rad_s + shift, fixed[i].angular_velocity_rad_s, 1e-12);
  }
  config.gyro_initial_bias_vector_rad_s = Eigen::Vector3d(0.0, std::nan(""), 0.0);
  EXPECT_NE(config.validate().find("gyro_initial_bias_vector_rad_s"), std::string::npos);
}

TEST(ImuModel, DeterministicPerSeed) {
  const CameraMotion motion(CameraMotionConfig(), 1, 0.0, 1.0);
  const ImuConfig config;
  const auto a = sampleImu(config, motion, 3, 0.0, 1.0), b = sampleImu(config, motion, 3, 0.0, 1.0);
  const auto c = sampleImu(config, motion, 4, 0.0, 1.0);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].stamp_s, b[i].stamp_s);
    EXPECT_EQ(a[i].angular_velocity_rad_s, b[i].angular_velocity_rad_s);
    EXPECT_EQ(a[i].linear_acceleration_m_s2, b[i].linear_acceleration_m_s2);
    EXPECT_EQ(a[i].true_bias_rad_s, b[i].true_bias_rad_s);
    EXPECT_NE(a[i].angular_velocity_rad_s, c[i].angular_velocity_rad_s);
  }
}

TEST(ImuModel, ValidateNamesTheField) {
  EXPECT_EQ("", ImuConfig().validate());
  ImuConfig config;
  config.rate_hz = 0.0;
  EXPECT_NE(std::string::npos, config.validate().find("rate_hz"));
  config = ImuConfig();
  config.imu_to_camera_rotation(0, 0) = 2.0;
  EXPECT_NE(std::string::npos, config.validate().find("imu_to_camera_rotation"));
  config = ImuConfig();
  config.imu_to_camera_rotation = -Eigen::Matrix3d::Identity();  // a reflection
  EXPECT_NE(std::string::npos, config.validate().find("imu_to_camera_rotation"));
  config = ImuConfig();
  config.gyro_bias_random_walk = -1.0;
  EXPECT_NE(std::string::npos, config.validate().find("gyro_bias_random_walk"));
  const CameraMotion motion(test::stillMotionConfig(), 1, 0.0, 1.0);
  EXPECT_THROW(sampleImu(config, motion, 1, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(sampleImu(ImuConfig(), motion, 1, 1.0, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
