// Times the compensation nodelet's per-frame work at the 360x270 grid: model inference (resample
// to the working grid, network, resample back) and warp (flow inversion + remap of an RGB frame)
// for each preset, then the whole per-frame chain of the two nodelets (gyro homographies, flow
// render, model, warp, ghost, colour) over the frame pairs of a bag. Flags: --help.
#include <ros/package.h>

#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/flow/flow_color.h"
#include "deep_ois/core/flow/flow_resample.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kTargetFps = 30.0;
constexpr double kTargetP95Ms = 15.0;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double percentile(std::vector<double> values, double fraction) {
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(std::ceil(fraction * values.size())) - 1;
  return values[std::min(index, values.size() - 1)];
}

// A gyro-like flow on the 360x270 grid: a rotation homography of a few pixels.
cv::Mat exampleFlow() {
  Eigen::Matrix3d K;
  K << 257, 0, 179.5, 0, 257, 134.5, 0, 0, 1;
  const deep_ois::CameraModel camera(360, 270, K);
  std::vector<Eigen::Matrix3d> homographies;
  for (int i = 0; i < 6; ++i) {
    Eigen::Matrix3d R;
    const double a = 0.01 + 0.002 * i;
    R << std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a);
    homographies.push_back(K * R * K.inverse());
  }
  cv::Mat flow;
  deep_ois::HomographyFlowRenderer(camera, cv::Size(360, 270), 6).render(homographies, flow);
  return flow;
}

// Mean absolute grey difference over the central half of the frames.
double centralDifference(const cv::Mat& a, const cv::Mat& b) {
  const cv::Rect centre(a.cols / 4, a.rows / 4, a.cols / 2, a.rows / 2);
  cv::Mat difference;
  cv::absdiff(a(centre), b(centre), difference);
  return cv::mean(difference)[0];
}

void report(const char* what, const std::vector<double>& ms) {
  std::printf("  %-34s median %7.2f ms   p95 %7.2f ms   (%zu runs)\n", what, percentile(ms, 0.5),
              percentile(ms, 0.95), ms.size());
}

}  // namespace

constexpr char kDescription[] =
    "Times the compensation nodelet's per-frame work at the 360x270 grid: model inference "
    "(resample "
    "to the working grid, network, resample back) and warp (flow inversion + remap of an RGB "
    "frame) "
    "for each preset, then the whole per-frame chain of the two nodelets (gyro homographies, flow "
    "render, model, warp, ghost, colour) over the frame pairs of a bag. Prints milliseconds per "
    "frame (median, 95th percentile) and frames per second against the target (>= 30 fps, p95 <= "
    "15 ms).";

int main(int argc, char** argv) {
  const std::string package = ros::package::getPath("deep_ois");
  std::string model_path = package + "/models/fast.pt", bag_path = package + "/bags/sample.bag";
  int threads = 1, frames = 200;
  deep_ois::ToolCommandLine command_line(
      "benchmark_compensation", kDescription,
      "Exit status: 0 measured (target met or not), 1 failed, 2 usage.");
  command_line.app()
      .add_option("--model", model_path,
                  "the model of the chain (default: the package's models/fast.pt)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.pt");
  command_line.app()
      .add_option("--bag", bag_path,
                  "the recording of the chain (default: the package's bags/sample.bag)")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag");
  command_line.addNumber("--threads", threads, "torch threads")->check(deep_ois::atLeast(1));
  command_line
      .addNumber("--frames", frames, "model runs per preset (paper preset: a twentieth, >= 5)")
      ->check(deep_ois::atLeast(1));
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    cv::setNumThreads(1);  // the nodelet's OpenCV work runs in its callback thread
    deep_ois::setTorchThreads(threads);
    std::printf(
        "benchmark_compensation: 360x270 grid, %d torch thread(s), OpenCV single-threaded\n",
        threads);
    const cv::Mat flow = exampleFlow();
    cv::Mat frame(270, 360, CV_8UC3);
    cv::randu(frame, 0, 255);

    for (const std::string preset : {"fast", "paper"}) {
      const deep_ois::CompensationModel model(deep_ois::presetMetadata(preset));
      // The nodelet's path: the model over consecutive pairs, with its motion history (30 fps).
      deep_ois::CompensationStream stream(model);
      constexpr std::int64_t kFrameNs = 33333333;
      std::int64_t stamp_ns = 0;
      const int runs = preset == "paper" ? std::max(5, frames / 20) : frames;
      for (int i = 0; i < 3; ++i, stamp_ns += kFrameNs)
        stream.compensate(flow, stamp_ns, stamp_ns + kFrameNs);  // warm-up
      std::vector<double> inference_ms, warp_ms;
      for (int i = 0; i < runs; ++i, stamp_ns += kFrameNs) {
        auto start = Clock::now();
        const cv::Mat compensated = stream.compensate(flow, stamp_ns, stamp_ns + kFrameNs);
        inference_ms.push_back(msSince(start));
        start = Clock::now();
        const cv::Mat aligned = deep_ois::warpOntoLaterFrame(frame, compensated);
        warp_ms.push_back(msSince(start));
      }
      const auto& m = model.metadata();
      std::printf("preset %s (widths", preset.c_str());
      for (int w : m.architecture.widths) std::printf(" %d", w);
      std::printf(", working grid %dx%d):\n", m.working_grid.width, m.working_grid.height);
      report("model inference", inference_ms);
      report("warp (invert flow + remap RGB)", warp_ms);
    }

    // The chain over a real bag with the shipped model and the nodelets' parameters.
    const deep_ois::CompensationModel model = deep_ois::CompensationModel::load(model_path);
    deep_ois::CompensationStream stream(model);
    const deep_ois::GyroFlowParameters params = deep_ois::loadGyroFlowParameters(
        deep_ois::YamlParameters(package + "/config/gyro_flow.yaml"));
    const deep_ois::BagSequence sequence = deep_ois::readBagSequence(bag_path);
    if (!sequence.camera || !sequence.imu_to_camera_rotation)
      throw std::runtime_error(bag_path + " lacks camera_info or tf");
    std::vector<deep_ois::BagFrame> images;
    deep_ois::BagFrameReader reader(bag_path, "/camera/image_raw");
    for (deep_ois::BagFrame f; reader.next(f);) {
      f.rgb = f.rgb.clone();  // next() may reuse the buffers
      f.gray = f.gray.clone();
      images.push_back(f);
    }
    deep_ois::RollingShutterConfig rs = params.rolling_shutter;
    rs.imu_to_camera_rotation = *sequence.imu_to_camera_rotation;
    const deep_ois::ImuSampleBuffer buffer = sequence.imuBuffer();
    const deep_ois::HomographyFlowRenderer renderer(*sequence.camera, params.grid_size,
                                                    rs.patch_count);
    std::vector<double> chain_ms;
    double resample_mean_px = 0.0, resample_max_px = 0.0, mean_flow_px = 0.0;  // per flow component
    double unaligned_diff = 0.0, gyro_diff = 0.0, aligned_diff = 0.0;
    cv::Mat gyro_flow;
    const auto chain_start = Clock::now();
    for (std::size_t k = 1; k < images.size(); ++k) {
      const auto start = Clock::now();
      const auto h = deep_ois::computeRollingShutterHomographies(
          buffer, params.integration, rs, sequence.camera->K(),
          sequence.secondsSinceBase(images[k - 1].stamp),
          sequence.secondsSinceBase(images[k].stamp));
      if (!h.ok()) continue;
      renderer.render(h.homographies, gyro_flow);
      const cv::Mat gyro_color = deep_ois::colorizeFlow(gyro_flow, params.color_max_flow_px);
      cv::Mat magnitude;
      cv::absdiff(gyro_flow, cv::Scalar::all(0), magnitude);
      const cv::Mat compensated =
          stream.compensate(gyro_flow, static_cast<std::int64_t>(images[k - 1].stamp.toNSec()),
                            static_cast<std::int64_t>(images[k].stamp.toNSec()));
      const cv::Mat map = deep_ois::inverseFlowMap(compensated, images[k].rgb.size());
      const cv::Mat aligned = deep_ois::warpWithInverseMap(images[k - 1].rgb, map);
      const cv::Mat ghost = deep_ois::ghostOverlay(aligned, images[k].rgb);
      const cv::Mat color = deep_ois::colorizeFlow(compensated, params.color_max_flow_px);
      chain_ms.push_back(msSince(start));
      // What the working grid loses: the gyro flow resampled to it and back.
      const cv::Mat round_trip = deep_ois::resampleFlow(
          deep_ois::resampleFlow(gyro_flow, model.metadata().working_grid), gyro_flow.size());
      cv::Mat error;
      cv::absdiff(round_trip, gyro_flow, error);
      resample_mean_px += cv::mean(error.reshape(1))[0];
      mean_flow_px += cv::mean(magnitude.reshape(1))[0];
      double largest = 0.0;
      cv::minMaxLoc(error.reshape(1), nullptr, &largest);
      resample_max_px = std::max(resample_max_px, largest);
      unaligned_diff += centralDifference(images[k - 1].gray, images[k].gray);
      const cv::Mat gray_map = deep_ois::inverseFlowMap(gyro_flow, images[k].rgb.size());
      gyro_diff += centralDifference(deep_ois::warpWithInverseMap(images[k - 1].gray, gray_map),
                                     images[k].gray);
      aligned_diff +=
          centralDifference(deep_ois::warpWithInverseMap(images[k - 1].gray, map), images[k].gray);
    }
    const double total_s = msSince(chain_start) / 1e3;
    if (chain_ms.empty()) throw std::runtime_error(bag_path + ": no frame pair with IMU coverage");
    const double fps = static_cast<double>(chain_ms.size()) / total_s;
    std::printf("chain on %s (%dx%d camera, %zu pairs, model %s): %.1f frames/s\n",
                bag_path.c_str(), sequence.camera->width(), sequence.camera->height(),
                chain_ms.size(), model_path.c_str(), fps);
    report("per frame (both nodelets' work)", chain_ms);
    const double n = static_cast<double>(chain_ms.size());
    std::printf(
        "  gyro flow through the %dx%d working grid and back: mean |change| %.4f, largest %.4f "
        "grid px "
        "(per component; mean |flow| %.3f)\n",
        model.metadata().working_grid.width, model.metadata().working_grid.height,
        resample_mean_px / n, resample_max_px, mean_flow_px / n);
    std::printf(
        "  mean central grey difference to frame b: frame a %.2f, warped by gyro flow %.2f, by "
        "model %.2f\n",
        unaligned_diff / n, gyro_diff / n, aligned_diff / n);
    const bool met = fps >= kTargetFps && percentile(chain_ms, 0.95) <= kTargetP95Ms;
    std::printf("target (>= %.0f fps, p95 <= %.0f ms per frame): %s\n", kTargetFps, kTargetP95Ms,
                met ? "met" : "NOT met");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_compensation: %s\n", e.what());
    return 1;
  }
  return 0;
}
