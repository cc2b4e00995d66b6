// Times the per-pair Fundamental Mixtures path of the offline ground-truth nodelet at the paper's
// 360x270, single-threaded: gray conversion, uniform FAST corners, KLT tracking and
// estimateFundamentalMixtures. Frames come from the simulator (RE category); rendering is not
// timed. Exit code 3 when the throughput target is missed. Flags: --help.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ros/package.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/ground_truth/fundamental_mixtures.h"
#include "deep_ois/core/sim/simulator.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/tools/support/command_line.h"

namespace deep_ois {
namespace {

constexpr double kTargetPairsPerSecond = 30.0;
constexpr int kWarmupPairs = 3;
constexpr std::uint32_t kSeed = 7;

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double percentile(std::vector<double> values, double fraction) {
  std::sort(values.begin(), values.end());
  const std::size_t index = static_cast<std::size_t>(std::ceil(fraction * values.size())) - 1;
  return values[std::min(index, values.size() - 1)];
}

cv::Mat toGray(const cv::Mat& frame) {
  if (frame.channels() == 1) return frame;
  cv::Mat gray;
  // The simulator renders RGB.
  cv::cvtColor(frame, gray, frame.channels() == 4 ? cv::COLOR_RGBA2GRAY : cv::COLOR_RGB2GRAY);
  return gray;
}

int run(int pairs) {
  // Single-threaded, as one nodelet callback runs.
  cv::setNumThreads(1);

  const sim::SimulatorConfig config =
      sim::loadSimulatorConfig(ros::package::getPath("deep_ois") + "/config/simulator/RE.yaml");
  const sim::Simulator simulator(config, kSeed, 2.0);
  const int available = simulator.frameCount() - 1;
  const int total = std::min(pairs + kWarmupPairs, available);
  if (total <= kWarmupPairs) {
    std::fprintf(stderr, "benchmark_fundamental_mixtures: the simulator made only %d frames\n",
                 simulator.frameCount());
    return 1;
  }
  const CameraModel& camera = simulator.camera().nominal();

  // Rendering is the simulator's cost, not the pipeline's: do it before the clock starts.
  std::vector<cv::Mat> frames;
  for (int k = 0; k <= total; ++k) frames.push_back(simulator.renderFrame(k));

  const CornerDetectorOptions detector;
  const KltOptions klt;
  const FundamentalMixturesOptions options;

  std::vector<double> total_ms, gray_ms, detect_ms, track_ms, solve_ms;
  std::map<std::string, int> models, statuses;
  int accepted = 0, rejected = 0;
  double tracks_sum = 0.0;
  // A fingerprint of the results, so that an optimisation can show it changed nothing but noise.
  double angle_sum_deg = 0.0, residual_sum_px = 0.0, inlier_sum = 0.0;
  std::vector<FeatureMatch> last_matches;
  for (int k = 1; k <= total; ++k) {
    const auto t0 = Clock::now();
    const cv::Mat gray_a = toGray(frames[k - 1]), gray_b = toGray(frames[k]);
    const double t_gray = millisecondsSince(t0);
    const auto t1 = Clock::now();
    const std::vector<cv::Point2f> corners = detectUniformCorners(gray_a, detector);
    const double t_detect = millisecondsSince(t1);
    const auto t2 = Clock::now();
    const std::vector<FeatureMatch> matches = trackFeatures(gray_a, gray_b, corners, klt);
    const double t_track = millisecondsSince(t2);
    const auto t3 = Clock::now();
    const FundamentalMixturesResult result = estimateFundamentalMixtures(matches, camera, options);
    const double t_solve = millisecondsSince(t3);
    if (k <= kWarmupPairs) continue;
    gray_ms.push_back(t_gray);
    detect_ms.push_back(t_detect);
    track_ms.push_back(t_track);
    solve_ms.push_back(t_solve);
    total_ms.push_back(t_gray + t_detect + t_track + t_solve);
    tracks_sum += matches.size();
    ++statuses[toString(result.status)];
    if (result.ok()) {
      ++accepted;
      ++models[toString(result.model)];
      for (const Eigen::Matrix3d& R : result.rotations) {
        angle_sum_deg += Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
      }
      residual_sum_px += result.median_rotation_residual_px;
      inlier_sum += result.inlier_count;
    } else {
      ++rejected;
    }
    last_matches = matches;
  }

  const int timed = static_cast<int>(total_ms.size());
  auto sum = [](const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return s;
  };
  const double all_ms = sum(total_ms);
  const double median_ms = percentile(total_ms, 0.5);
  const double pairs_per_second = 1000.0 * timed / all_ms;

  std::printf(
      "benchmark_fundamental_mixtures: %d pairs of %dx%d RE frames (seed %u) after %d warm-up, "
      "single thread, %.0f tracks per pair on average\n",
      timed, camera.width(), camera.height(), kSeed, kWarmupPairs, tracks_sum / timed);
  std::printf("per pair: median %.2f ms, p95 %.2f ms, mean %.2f ms -> %.1f pairs/s\n", median_ms,
              percentile(total_ms, 0.95), all_ms / timed, pairs_per_second);
  std::printf("%-32s %10s %10s %8s\n", "stage", "median ms", "p95 ms", "share");
  const std::pair<const char*, const std::vector<double>*> stages[] = {
      {"gray conversion", &gray_ms},
      {"detectUniformCorners", &detect_ms},
      {"trackFeatures", &track_ms},
      {"estimateFundamentalMixtures", &solve_ms}};
  for (const auto& stage : stages) {
    std::printf("%-32s %10.2f %10.2f %7.1f%%\n", stage.first, percentile(*stage.second, 0.5),
                percentile(*stage.second, 0.95), 100.0 * sum(*stage.second) / all_ms);
  }
  std::printf("accepted %d, rejected %d\n", accepted, rejected);
  for (const auto& entry : statuses) {
    std::printf("  status %-28s %d\n", entry.first.c_str(), entry.second);
  }
  for (const auto& entry : models) {
    std::printf("  model  %-28s %d\n", entry.first.c_str(), entry.second);
  }

  std::printf(
      "fingerprint: sum of rotation angles %.6f deg, sum of median residuals %.6f px, "
      "%.0f inliers\n",
      angle_sum_deg, residual_sum_px, inlier_sum);

  // The ablation, for reference (once, on the last pair's tracks).
  const auto t_global = Clock::now();
  const FundamentalMixturesResult global = estimateGlobalFundamental(last_matches, camera, options);
  std::printf("estimateGlobalFundamental (reference, one call, %zu tracks): %.2f ms, %s, %s\n",
              last_matches.size(), millisecondsSince(t_global), toString(global.status),
              toString(global.model));

  const bool met = pairs_per_second >= kTargetPairsPerSecond;
  std::printf("target >= %.0f pairs/s: %s (%.1f pairs/s)\n", kTargetPairsPerSecond,
              met ? "met" : "MISSED", pairs_per_second);
  return met ? 0 : 3;
}

}  // namespace
}  // namespace deep_ois

constexpr char kDescription[] =
    "Times the per-pair Fundamental Mixtures path of the offline ground-truth nodelet at the "
    "paper's "
    "360x270, single-threaded: gray conversion, uniform FAST corners, KLT tracking and "
    "estimateFundamentalMixtures. Frames come from the simulator (RE category); rendering is not "
    "timed. Prints milliseconds per pair and pairs per second.";

int main(int argc, char** argv) {
  int pairs = 60;
  deep_ois::ToolCommandLine command_line(
      "benchmark_fundamental_mixtures", kDescription,
      "Exit status: 0 target met, 1 failed, 2 usage, 3 throughput target missed.");
  command_line.addNumber("pairs", pairs, "frame pairs to time")->check(deep_ois::atLeast(1));
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    return deep_ois::run(pairs);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_fundamental_mixtures: %s\n", e.what());
    return 1;
  }
}
