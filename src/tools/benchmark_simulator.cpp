// Times the simulator's renderer: frames of an RE scene (photographs at depth, hand-held motion,
// OIS, rolling shutter, supersampling, motion blur, noise) on one thread, as one core of a data
// set build runs it. Prints frames per second and the per-frame median and 95th percentile.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <opencv2/core/utility.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/sim/rolling_shutter_renderer.h"
#include "deep_ois/tools/support/command_line.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kTargetFps = 20.0;  // at 360x270, supersampling 2, 3 exposure samples
constexpr int kWarmupFrames = 3;

double percentile(std::vector<double> values, double fraction) {
  std::sort(values.begin(), values.end());
  const std::size_t index = static_cast<std::size_t>(std::ceil(fraction * values.size())) - 1;
  return values[std::min(index, values.size() - 1)];
}

int run(int frames, std::uint32_t seed, const std::vector<double>& distortion) {
  cv::setNumThreads(1);  // one core: the data set tools run one simulator per core
  SensorConfig sensor;   // 360x270, 70 degrees, supersampling 2, 3 exposure samples, noise on
  if (!distortion.empty()) sensor.distortion = distortion;
  const double frame_period_s = 1.0 / sensor.frame_rate_hz;
  const double end_s = (frames + kWarmupFrames) * frame_period_s + 0.25;
  const CameraMotion motion(CameraMotionConfig(), seed, -0.25, end_s);
  const double focal_px = nominalCamera(sensor).K()(0, 0);
  const OisModel ois(OisConfig(), motion, focal_px, seed);
  const SimCamera camera(sensor, motion, ois);

  const auto build_start = std::chrono::steady_clock::now();
  Scene scene;
  try {
    scene =
        buildScene(SceneConfig(), Category::kRegular, seed, motion, focal_px, sensor.supersampling);
  } catch (const std::exception& e) {
    std::cerr << "benchmark_simulator: " << e.what() << "\n";
    return 1;
  }
  const double build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - build_start)
          .count();
  const RollingShutterRenderer renderer(scene, camera);

  std::vector<double> per_frame_ms;
  double checksum = 0.0;  // keeps the optimiser from dropping the work
  const auto start = std::chrono::steady_clock::now();
  auto measured_start = start;
  for (int k = 0; k < frames + kWarmupFrames; ++k) {
    if (k == kWarmupFrames) measured_start = std::chrono::steady_clock::now();
    const auto frame_start = std::chrono::steady_clock::now();
    const cv::Mat image = renderer.render(k * frame_period_s, static_cast<std::uint64_t>(k), seed);
    const auto frame_stop = std::chrono::steady_clock::now();
    checksum += image.at<cv::Vec3b>(image.rows / 2, image.cols / 2)[1];
    if (k >= kWarmupFrames) {
      per_frame_ms.push_back(
          std::chrono::duration<double, std::milli>(frame_stop - frame_start).count());
    }
  }
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - measured_start).count();
  const double fps = frames / total_s;
  const double median_ms = percentile(per_frame_ms, 0.5);

  std::printf(
      "benchmark_simulator: RE scene, %dx%d, supersampling %d, %d exposure samples, %s, "
      "noise on, %zu planes (built in %.0f ms), single thread\n",
      sensor.width_px, sensor.height_px, sensor.supersampling, sensor.exposure_samples,
      distortion.empty() ? "no distortion" : "plumb_bob distortion", scene.planes().size(),
      build_ms);
  std::printf("%d frames: %.1f frames/s, median %.2f ms, p95 %.2f ms per frame (checksum %.0f)\n",
              frames, fps, median_ms, percentile(per_frame_ms, 0.95), checksum);
  const bool met = 1000.0 / median_ms >= kTargetFps;
  std::printf("target: >= %.0f frames/s (median): %s\n", kTargetFps, met ? "met" : "MISSED");
  return met ? 0 : 3;
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois

constexpr char kDescription[] =
    "Times the simulator's renderer: frames of an RE scene (photographs at depth, hand-held "
    "motion, "
    "OIS, rolling shutter, supersampling, motion blur, noise) on one thread, as one core of a data "
    "set build runs it. Prints frames per second and the per-frame median and 95th percentile in "
    "milliseconds, and whether the target (>= 20 frames/s at the median) is met.";

int main(int argc, char** argv) {
  int frames = 60;
  std::uint32_t seed = 1;
  bool with_distortion = false;
  deep_ois::ToolCommandLine command_line(
      "benchmark_simulator", kDescription,
      "Exit status: 0 target met, 1 failed, 2 usage, 3 target missed.");
  command_line.addNumber("--frames", frames, "frames to render")->check(deep_ois::atLeast(1));
  command_line.addNumber("--seed", seed, "the simulator's seed");
  command_line.app().add_flag("--distortion", with_distortion,
                              "render through a phone lens's plumb_bob distortion");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  static const std::vector<double> kPhoneLensDistortion = {-0.12, 0.03, 0.0005, -0.0003, 0.0};
  return deep_ois::sim::run(frames, seed,
                            with_distortion ? kPhoneLensDistortion : std::vector<double>{});
}
