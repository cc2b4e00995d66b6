// describeTrainingSetCamera: the camera a network's metadata records from its training set.
#include <gtest/gtest.h>

#include "deep_ois/core/ground_truth/training_set_camera.h"

namespace deep_ois {
namespace {

TrainingSample pair(int width, double focal_px, std::int64_t stamp_a_ns, std::int64_t interval_ns) {
  Eigen::Matrix3d K;
  K << focal_px, 0, 0.5 * (width - 1), 0, focal_px, 0.5 * (0.75 * width - 1), 0, 0, 1;
  TrainingSample sample;
  sample.camera = CameraModel(width, static_cast<int>(0.75 * width), K);
  sample.stamp_a_ns = stamp_a_ns;
  sample.stamp_b_ns = stamp_a_ns + interval_ns;
  return sample;
}

TEST(TrainingSetCamera, OneCameraWithItsFrameRateAndAnUnknownReadout) {
  constexpr std::int64_t kIntervalNs = 33'333'333;  // 30 fps
  std::vector<TrainingSample> samples;
  for (int k = 0; k < 20; ++k) samples.push_back(pair(640, 500.0, k * kIntervalNs, kIntervalNs));
  samples.push_back(pair(640, 500.0, 21 * kIntervalNs, 2 * kIntervalNs));  // across a lost frame
  samples.push_back(pair(640, 502.0, 24 * kIntervalNs, kIntervalNs));      // focal within 1 %: the same
  const TrainingSetCamera described = describeTrainingSetCamera(samples);
  EXPECT_EQ(described.cameras, 1u);
  ASSERT_TRUE(described.camera.known());
  EXPECT_EQ(described.camera.width, 640);
  EXPECT_EQ(described.camera.height, 480);
  EXPECT_DOUBLE_EQ(described.camera.fx, 500.0);
  EXPECT_NEAR(described.camera.frame_rate_hz, 30.0, 1e-6);
  EXPECT_FALSE(described.camera.readoutKnown());
}

TEST(TrainingSetCamera, SeveralCamerasMakeAGenericModel) {
  const TrainingSetCamera described =
      describeTrainingSetCamera({pair(640, 500.0, 0, 33'333'333), pair(1280, 1000.0, 0, 33'333'333)});
  EXPECT_EQ(described.cameras, 2u);
  EXPECT_FALSE(described.camera.known());
  EXPECT_EQ(describeTrainingSetCamera({}).cameras, 0u);
}

}  // namespace
}  // namespace deep_ois
