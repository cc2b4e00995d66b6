// The backward map built on the working grid (backward_map.h, what the compensation nodelet warps
// with) against the per-camera-pixel inversion it replaced (inverseFlowMap) on every frame pair of
// bags/sample.bag: its gyro flows and, with the shipped model, the compensated flows the nodelet
// warps by, at the bag's 256x192 and with the same motion at 1920x1080. Largest difference over
// the whole image <= 0.01 px. No roscore needed.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#ifdef DEEP_OIS_WITH_NET
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#endif

namespace deep_ois {
namespace {

constexpr double kTolerancePx = 0.01;
// At 1920x1080 the reference inversion takes ~0.2 s per flow: every third pair (20 of them).
constexpr std::size_t kStride1080p = 3;

std::string sourcePath(const std::string& relative) { return std::string(DEEP_OIS_SOURCE_DIR) + "/" + relative; }

// The gyro flow of every frame pair of the sample bag, as the gyro flow nodelet renders it.
struct SampleBagFlows {
  cv::Size camera_size;
  std::vector<cv::Mat> gyro;
  std::vector<std::pair<std::int64_t, std::int64_t>> stamps_ns;
};

SampleBagFlows sampleBagFlows() {
  const GyroFlowParameters params = loadGyroFlowParameters(YamlParameters(sourcePath("config/gyro_flow.yaml")));
  const BagSequence sequence = readBagSequence(sourcePath("bags/sample.bag"));
  SampleBagFlows flows;
  if (!sequence.camera || !sequence.imu_to_camera_rotation) return flows;
  flows.camera_size = cv::Size(sequence.camera->width(), sequence.camera->height());
  RollingShutterConfig rs = params.rolling_shutter;
  rs.imu_to_camera_rotation = *sequence.imu_to_camera_rotation;
  const ImuSampleBuffer buffer = sequence.imuBuffer();
  const HomographyFlowRenderer renderer(*sequence.camera, params.grid_size, rs.patch_count);
  for (std::size_t k = 1; k < sequence.frame_stamps.size(); ++k) {
    const auto h = computeRollingShutterHomographies(buffer, params.integration, rs, sequence.camera->K(),
                                                     sequence.secondsSinceBase(sequence.frame_stamps[k - 1]),
                                                     sequence.secondsSinceBase(sequence.frame_stamps[k]));
    if (!h.ok()) continue;
    cv::Mat flow;
    renderer.render(h.homographies, flow);
    flows.gyro.push_back(flow);
    flows.stamps_ns.emplace_back(static_cast<std::int64_t>(sequence.frame_stamps[k - 1].toNSec()),
                                 static_cast<std::int64_t>(sequence.frame_stamps[k].toNSec()));
  }
  return flows;
}

// Largest |fast - reference| over every pixel and both components, over every `stride`-th flow.
double largestMapDifferencePx(const std::vector<cv::Mat>& flows, cv::Size camera_size, std::size_t stride = 1) {
  double largest = 0.0;
  for (std::size_t k = 0; k < flows.size(); k += stride) {
    const cv::Mat& flow = flows[k];
    cv::Mat difference;
    cv::absdiff(backwardMapFromGrid(flow, camera_size, 3), inverseFlowMap(flow, camera_size, 3), difference);
    double worst = 0.0;
    cv::Point where;
    cv::minMaxLoc(difference.reshape(1), nullptr, &worst, nullptr, &where);
    if (worst > largest) {
      std::printf("  pair %zu: %.5f px at camera pixel (%d, %d)\n", k, worst, where.x / 2, where.y);
      largest = worst;
    }
  }
  return largest;
}

TEST(BackwardMapSampleBag, GyroFlowsWithinOneHundredthOfAPixel) {
  const SampleBagFlows flows = sampleBagFlows();
  ASSERT_GE(flows.gyro.size(), 50u) << "the sample bag's frame pairs with IMU coverage";
  const double at_bag_size = largestMapDifferencePx(flows.gyro, flows.camera_size);
  const double at_1080p = largestMapDifferencePx(flows.gyro, cv::Size(1920, 1080), kStride1080p);
  RecordProperty("largest_px_bag_size", std::to_string(at_bag_size));
  RecordProperty("largest_px_1080p", std::to_string(at_1080p));
  std::printf("gyro flows: largest map difference %.5f px at %dx%d, %.5f px at 1920x1080\n", at_bag_size,
              flows.camera_size.width, flows.camera_size.height, at_1080p);
  EXPECT_LE(at_bag_size, kTolerancePx);
  EXPECT_LE(at_1080p, kTolerancePx);
}

#ifdef DEEP_OIS_WITH_NET
TEST(BackwardMapSampleBag, CompensatedFlowsWithinOneHundredthOfAPixel) {
  const SampleBagFlows flows = sampleBagFlows();
  ASSERT_GE(flows.gyro.size(), 50u);
  const CompensationModel model = CompensationModel::load(sourcePath("models/fast.pt"));
  CompensationStream stream(model);
  std::vector<cv::Mat> compensated;
  for (std::size_t k = 0; k < flows.gyro.size(); ++k) {
    compensated.push_back(stream.compensate(flows.gyro[k], flows.stamps_ns[k].first, flows.stamps_ns[k].second));
  }
  const double at_bag_size = largestMapDifferencePx(compensated, flows.camera_size);
  const double at_1080p = largestMapDifferencePx(compensated, cv::Size(1920, 1080), kStride1080p);
  std::printf("compensated flows: largest map difference %.5f px at %dx%d, %.5f px at 1920x1080\n", at_bag_size,
              flows.camera_size.width, flows.camera_size.height, at_1080p);
  EXPECT_LE(at_bag_size, kTolerancePx);
  EXPECT_LE(at_1080p, kTolerancePx);
}
#endif

}  // namespace
}  // namespace deep_ois
