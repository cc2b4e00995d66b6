// Times the per-frame gyro flow path of the gyro flow nodelet: rolling-shutter homographies from
// a 400 Hz gyro buffer (6 patches) plus the dense flow render, single-threaded, per frame pair.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <opencv2/core/utility.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/tools/support/command_line.h"

namespace deep_ois {
namespace {

constexpr int kPatches = 6;
constexpr int kWarmupFrames = 30;
constexpr double kTargetMedianMs = 1.0;  // at the network's 360x270 grid
constexpr double kHorizontalFovDeg = 70.0;

struct BenchCase {
  std::string name;
  CameraModel camera;
  cv::Size grid;
};

CameraModel cameraWithFov(int width, int height, const std::vector<double>& plumb_bob = {}) {
  const double f = 0.5 * width / std::tan(0.5 * kHorizontalFovDeg * M_PI / 180.0);
  Eigen::Matrix3d K;
  K << f, 0, 0.5 * (width - 1), 0, f, 0.5 * (height - 1), 0, 0, 1;
  return CameraModel(width, height, K, plumb_bob);
}

double percentile(std::vector<double> values, double fraction) {
  std::sort(values.begin(), values.end());
  const std::size_t index = static_cast<std::size_t>(std::ceil(fraction * values.size())) - 1;
  return values[std::min(index, values.size() - 1)];
}

int run(int frames) {
  // Single-threaded, as the nodelet's callback runs; keeps OpenCV from spreading work.
  cv::setNumThreads(1);

  // Hand-held motion sampled by a 400 Hz phone gyro, as the simulator makes it.
  constexpr double kFrameRateHz = 30.0;
  const double duration_s = (frames + kWarmupFrames + 2) / kFrameRateHz;
  const sim::CameraMotion motion(sim::CameraMotionConfig{}, 1, -0.2, duration_s + 0.2);
  const sim::ImuConfig imu_config;
  const std::vector<sim::ImuMeasurement> imu =
      sim::sampleImu(imu_config, motion, 1, -0.1, duration_s + 0.1);
  ImuSampleBuffer buffer(duration_s + 1.0);
  for (const sim::ImuMeasurement& m : imu) buffer.add({m.stamp_s, m.angular_velocity_rad_s});
  RollingShutterConfig rolling;
  rolling.patch_count = kPatches;
  rolling.readout_time_s = 0.022;
  rolling.imu_to_camera_rotation = imu_config.imu_to_camera_rotation;
  const IntegrationOptions integration;
  auto frameStamp = [&](int k) { return k / kFrameRateHz; };

  const std::vector<BenchCase> cases = {
      {"360x270 camera, 360x270 grid", cameraWithFov(360, 270), cv::Size(360, 270)},
      {"1920x1080 camera, 1920x1080 grid", cameraWithFov(1920, 1080), cv::Size(1920, 1080)},
      {"360x270 camera + plumb_bob, 360x270 grid",
       cameraWithFov(360, 270, {-0.12, 0.03, 0.0005, -0.0003, 0.0}), cv::Size(360, 270)},
      {"1920x1080 camera, 360x270 grid (network)", cameraWithFov(1920, 1080), cv::Size(360, 270)},
  };

  std::printf(
      "benchmark_gyro_flow: %d frame pairs per case after %d warm-up, %d patches, "
      "%.0f Hz gyro, single thread\n",
      frames, kWarmupFrames, kPatches, imu_config.rate_hz);
  std::printf("%-44s %10s %10s %14s\n", "case", "median ms", "p95 ms", "of which H ms");
  bool target_met = true;
  double checksum = 0.0;  // keeps the optimiser from dropping the work
  for (const BenchCase& bench : cases) {
    const HomographyFlowRenderer renderer(bench.camera, bench.grid, kPatches);
    cv::Mat flow;
    std::vector<double> per_frame_ms, homography_ms;
    per_frame_ms.reserve(frames);
    homography_ms.reserve(frames);
    for (int k = 0; k < frames + kWarmupFrames; ++k) {
      const auto start = std::chrono::steady_clock::now();
      const RollingShutterHomographies homographies = computeRollingShutterHomographies(
          buffer, integration, rolling, bench.camera.K(), frameStamp(k), frameStamp(k + 1));
      const auto integrated = std::chrono::steady_clock::now();
      if (!homographies.ok()) {
        std::cerr << "benchmark_gyro_flow: " << homographies.reason << "\n";
        return 1;
      }
      renderer.render(homographies.homographies, flow);
      const auto stop = std::chrono::steady_clock::now();
      checksum += flow.at<cv::Vec2f>(flow.rows / 2, flow.cols / 2)[0];
      if (k >= kWarmupFrames) {
        per_frame_ms.push_back(std::chrono::duration<double, std::milli>(stop - start).count());
        homography_ms.push_back(
            std::chrono::duration<double, std::milli>(integrated - start).count());
      }
    }
    const double median = percentile(per_frame_ms, 0.5);
    std::printf("%-44s %10.3f %10.3f %14.3f\n", bench.name.c_str(), median,
                percentile(per_frame_ms, 0.95), percentile(homography_ms, 0.5));
    if (bench.grid == cv::Size(360, 270) && !bench.camera.hasDistortion() &&
        bench.camera.width() == 360) {
      target_met = median <= kTargetMedianMs;
    }
  }
  std::printf("target: median <= %.1f ms per frame at 360x270: %s (checksum %.3f)\n",
              kTargetMedianMs, target_met ? "met" : "MISSED", checksum);
  return target_met ? 0 : 3;
}

}  // namespace
}  // namespace deep_ois

constexpr char kDescription[] =
    "Times the per-frame gyro flow path of the gyro flow nodelet: rolling-shutter homographies "
    "from "
    "a 400 Hz gyro buffer (6 patches) plus the dense flow render, single-threaded, per frame pair, "
    "at several grid sizes. Prints milliseconds per frame (median, 95th percentile) and whether "
    "the "
    "target (median <= 1 ms at 360x270) is met.";

int main(int argc, char** argv) {
  int frames = 300;
  deep_ois::ToolCommandLine command_line(
      "benchmark_gyro_flow", kDescription,
      "Exit status: 0 target met, 1 failed, 2 usage, 3 target missed.");
  command_line.addNumber("--frames", frames, "frame pairs per case")->check(deep_ois::atLeast(1));
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  return deep_ois::run(frames);
}
