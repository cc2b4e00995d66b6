// Times both live nodelets' per-frame work (the gyro flow nodelet, then the compensation nodelet
// with every output subscribed) at robot camera resolutions, per stage, on synthetic frames and a
// synthetic hand-held gyro, with the same core calls as the nodelets; and, in the same run, a bare
// cv::remap of the same frame with the same map, so that the chain reads as a multiple of one remap.
//
//   benchmark_compensation [--model models/stabiliser_generic.yaml | models/fast.pt] [--frames 200] [--threads 1] [--warp-threads 1]
//                          [--sizes 256x192,640x480,1280x720,1920x1080]
//
// One core by default: torch and OpenCV single-threaded (--threads / --warp-threads raise them).
// Stages (see docs/benchmarks.md): gyro flow (gyro integration, per-patch homographies, flow on the
// working grid), inference (the model through CompensationStream), map build (flow inverted on the
// grid, backward map to camera pixels), remap (frame a onto frame b: aligned/image_raw), ghost,
// colour (gyro_flow/color and compensated_flow/color), message conversion (the GyroFlow messages,
// image views in, output messages out). Beside the chain: the map built from the row-patch
// homographies instead (PatchHomographyMapBuilder), the per-pixel inversion the map build replaced.
#include <cv_bridge/cv_bridge.h>
#include <ros/package.h>
#include <sensor_msgs/image_encodings.h>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <boost/make_shared.hpp>

#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/flow_color.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/flow/patch_homography_map.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/ros/live/stabiliser_flow_compensator.h"
#include "deep_ois/net/compensation_stream.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/messages/conversions.h"

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kFramePeriodS = 1.0 / 30.0;
constexpr double kImuRateHz = 400.0;
constexpr std::size_t kReferenceRuns = 10;
// Pairs run before the timed ones (the first ones after start-up run slower for a while).
constexpr int kWarmUpPairs = 30;

// CPU time of the calling thread: what the chain costs its one core even while other processes
// share the machine (wall time then also counts the waits for a core).
double threadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double percentile(std::vector<double> values, double fraction) {
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(std::ceil(fraction * values.size())) - 1;
  return values[std::min(index, values.size() - 1)];
}

double mean(const std::vector<double>& values) {
  return std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

// A hand-held camera: smooth turns of a few tenths of rad/s about all three axes (camera frame).
Eigen::Vector3d angularVelocity(double t_s) {
  return Eigen::Vector3d(0.4 * std::sin(2 * M_PI * 0.7 * t_s), 0.6 * std::sin(2 * M_PI * 0.45 * t_s + 1.0),
                         0.15 * std::sin(2 * M_PI * 0.9 * t_s + 2.0));
}

// A 70-degree camera of `size`, principal point at the centre.
deep_ois::CameraModel cameraOfSize(cv::Size size) {
  const double f = 0.5 * size.width / std::tan(35.0 * M_PI / 180.0);
  Eigen::Matrix3d K;
  K << f, 0, 0.5 * (size.width - 1), 0, f, 0.5 * (size.height - 1), 0, 0, 1;
  return deep_ois::CameraModel(size.width, size.height, K);
}

// A textured rgb8 frame (blurred noise): the warp's cost does not depend on the content.
sensor_msgs::ImagePtr texturedFrame(cv::Size size, int seed, const ros::Time& stamp) {
  cv::Mat view;
  std_msgs::Header header;
  header.stamp = stamp;
  header.frame_id = "camera";
  sensor_msgs::ImagePtr msg = deep_ois::makeImageMsg(header, sensor_msgs::image_encodings::RGB8, size, view);
  cv::RNG rng(seed);
  rng.fill(view, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(view, view, cv::Size(5, 5), 1.5);
  return msg;
}

struct Stage {
  const char* name;
  std::vector<double> ms;
};

cv::Size parseSize(const std::string& text) {
  int w = 0, h = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> w >> x >> h) || x != 'x' || w < 2 || h < 2) throw std::invalid_argument("bad size " + text + " (WxH)");
  return cv::Size(w, h);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string package = ros::package::getPath("deep_ois");
  // The launch files' default (launch/deep_ois.launch): what a user runs is what is timed.
  std::string model_path = package + "/models/stabiliser_generic.yaml";
  std::string sizes_text = "256x192,640x480,1280x720,1920x1080";
  int torch_threads = 1, warp_threads = 1, frames = 200;
  deep_ois::ToolCommandLine command_line(
      "benchmark_compensation",
      "Times both live nodelets' per-frame work at robot camera resolutions, per stage, on "
      "synthetic frames and a synthetic hand-held gyro, with a bare cv::remap of the same frame as "
      "the yardstick (docs/benchmarks.md). One core by default.",
      "Exit status: 0 done, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--model", model_path, "the compensation model: a stabiliser model .yaml or a network .pt")
      ->check(deep_ois::existingFile())
      ->capture_default_str()
      ->type_name("FILE");
  command_line.addNumber("--frames", frames, "frame pairs timed per camera size (>= 10)")
      ->check(CLI::Range(10, 1000000));
  command_line.addNumber("--threads", torch_threads, "torch intra-op threads (>= 1)")
      ->check(CLI::Range(1, 256));
  command_line.addNumber("--warp-threads", warp_threads, "OpenCV threads of the warp (>= 1)")
      ->check(CLI::Range(1, 256));
  app.add_option("--sizes", sizes_text, "camera sizes, comma-separated WIDTHxHEIGHT")
      ->capture_default_str()
      ->type_name("WxH,...");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    if (frames < 10 || torch_threads < 1 || warp_threads < 1) throw std::invalid_argument("--frames >= 10, threads >= 1");
    std::vector<cv::Size> sizes;
    std::stringstream list(sizes_text);
    for (std::string item; std::getline(list, item, ',');) sizes.push_back(parseSize(item));

    cv::setNumThreads(warp_threads);  // as the nodelet's ~warp_threads
    deep_ois::setTorchThreads(torch_threads);
    // A learned stabiliser model (.yaml) or the network (.pt), as the nodelet's ~model.
    const bool stabiliser = deep_ois::isStabiliserModelPath(model_path);
    std::unique_ptr<deep_ois::CompensationModel> model;
    std::unique_ptr<deep_ois::StabiliserModelFile> stabiliser_model;
    if (stabiliser) {
      stabiliser_model = std::make_unique<deep_ois::StabiliserModelFile>(deep_ois::StabiliserModelFile::load(model_path));
    } else {
      model = std::make_unique<deep_ois::CompensationModel>(deep_ois::CompensationModel::load(model_path));
    }
    const deep_ois::GyroFlowParameters params =
        deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(package + "/config/gyro_flow.yaml"));
    if (stabiliser) {
      std::printf("benchmark_compensation: learned stabiliser model %s, flow grid %dx%d, %d OpenCV thread(s), %d "
                  "frame pairs per size, %u hardware threads\n",
                  model_path.c_str(), params.grid_size.width, params.grid_size.height, warp_threads, frames,
                  std::thread::hardware_concurrency());
    } else {
      const auto& m = model->metadata();
      std::printf("benchmark_compensation: model %s (preset %s, network grid %dx%d), flow grid %dx%d, %d torch "
                  "thread(s), %d OpenCV thread(s), %d frame pairs per size, %u hardware threads\n",
                  model_path.c_str(), m.preset.c_str(), m.working_grid.width, m.working_grid.height,
                  params.grid_size.width, params.grid_size.height, torch_threads, warp_threads, frames,
                  std::thread::hardware_concurrency());
    }

    // The synthetic gyro, shared by all sizes: 400 Hz over the whole run.
    const double duration_s = (frames + kWarmUpPairs + 12) * kFramePeriodS + 1.0;
    deep_ois::ImuSampleBuffer imu(duration_s + 1.0);
    for (double t = 0.0; t <= duration_s; t += 1.0 / kImuRateHz) imu.add({t, angularVelocity(t)});

    std::printf("\n%-10s %-20s %9s %9s %9s\n", "camera", "stage", "median ms", "p95 ms", "mean ms");
    struct Summary {
      cv::Size size;
      double fps, median_ms, p95_ms, remap_median_ms, ratio;
    };
    std::vector<Summary> summaries;
    for (const cv::Size size : sizes) {
      const deep_ois::CameraModel camera = cameraOfSize(size);
      deep_ois::RollingShutterConfig rs = params.rolling_shutter;
      rs.imu_to_camera_rotation = Eigen::Matrix3d::Identity();
      const deep_ois::HomographyFlowRenderer renderer(camera, params.grid_size, rs.patch_count);
      std::unique_ptr<deep_ois::CompensationStream> stream;
      std::unique_ptr<deep_ois::StabiliserFlowCompensator> stabiliser_compensator;
      if (stabiliser) {
        stabiliser_compensator = std::make_unique<deep_ois::StabiliserFlowCompensator>(*stabiliser_model);
      } else {
        stream = std::make_unique<deep_ois::CompensationStream>(*model);
      }
      deep_ois::GyroFlowMetadata metadata;
      metadata.camera = camera;
      metadata.distortion_model = "plumb_bob";
      metadata.rolling_shutter = rs;
      metadata.header.frame_id = "camera";
      const ros::Time base(1000.0);
      const sensor_msgs::ImagePtr images[2] = {texturedFrame(size, 1, base), texturedFrame(size, 2, base)};

      std::vector<Stage> stages = {{"gyro flow", {}}, {"inference", {}},      {"map build", {}},
                                   {"remap", {}},     {"ghost", {}},          {"colour", {}},
                                   {"message conversion", {}}};
      std::vector<double> chain_ms, bare_remap_ms, one_by_one_share, chain_cpu_ms, bare_remap_cpu_ms, reference_ms;
      std::vector<double> homography_map_ms;
      deep_ois::FixedPointMap map, homography_map;
      // The warp's other input: the map straight from the six row-patch homographies (what a
      // compensator that outputs homographies warps by), timed beside the chain, not in it.
      const deep_ois::PatchHomographyMapBuilder homography_builder(camera, rs.patch_count);
      cv::Mat gyro_flow, bare_out;
      for (int k = 0; k < frames + kWarmUpPairs; ++k) {
        const double stamp_a_s = 0.5 + k * kFramePeriodS, stamp_b_s = stamp_a_s + kFramePeriodS;
        sensor_msgs::Image& image_a = *images[k % 2];
        sensor_msgs::Image& image_b = *images[(k + 1) % 2];
        image_a.header.stamp = base + ros::Duration(stamp_a_s);
        image_b.header.stamp = base + ros::Duration(stamp_b_s);
        double ms[7] = {0, 0, 0, 0, 0, 0, 0};
        const double cpu_start_ms = threadCpuMs();

        // Gyro flow nodelet: homographies, the flow on the grid, its message and colour image.
        auto start = Clock::now();
        const auto h = deep_ois::computeRollingShutterHomographies(imu, params.integration, rs, camera.K(),
                                                                   stamp_a_s, stamp_b_s);
        if (!h.ok()) throw std::runtime_error("synthetic gyro does not cover frame pair " + std::to_string(k));
        renderer.render(h.homographies, gyro_flow);
        ms[0] += msSince(start);
        start = Clock::now();
        metadata.header.stamp = image_b.header.stamp;
        metadata.previous_stamp = image_a.header.stamp;
        // The gyro stream the message carries (as gyro_flow_ros), relative to frame b's stamp.
        metadata.camera_rates.clear();
        for (deep_ois::CameraRateSample rate : deep_ois::cameraRates(
                 imu, rs.imu_to_camera_rotation, deep_ois::patchImuTime(rs, stamp_a_s, 0) - deep_ois::kStabiliserWarmUpS,
                 deep_ois::patchImuTime(rs, stamp_b_s, rs.patch_count - 1))) {
          rate.stamp_s -= stamp_b_s;
          metadata.camera_rates.push_back(rate);
        }
        auto gyro_msg = boost::make_shared<deep_ois::GyroFlow>();
        deep_ois::fillGyroFlowMsg(metadata, h.homographies, gyro_flow, *gyro_msg);
        cv::Mat gyro_color;
        const sensor_msgs::ImagePtr gyro_color_msg =
            deep_ois::makeImageMsg(gyro_msg->header, sensor_msgs::image_encodings::RGB8, gyro_flow.size(), gyro_color);
        ms[6] += msSince(start);
        start = Clock::now();
        deep_ois::colorizeFlow(gyro_flow, params.color_max_flow_px, gyro_color);
        ms[5] += msSince(start);

        // Compensation nodelet, every output subscribed (CompensationRos::process).
        start = Clock::now();
        std::vector<Eigen::Matrix3d> homographies;
        cv::Mat flow_view;
        const std::string problem = deep_ois::readGyroFlowMsg(*gyro_msg, homographies, flow_view);
        if (!problem.empty()) throw std::runtime_error(problem);
        ms[6] += msSince(start);
        start = Clock::now();
        cv::Mat compensated;
        std::vector<Eigen::Matrix3d> compensated_homographies;  // a stabiliser model's
        if (stabiliser) {
          deep_ois::StabiliserFlowResult result = stabiliser_compensator->compensate(*gyro_msg);
          if (!result.ok) throw std::runtime_error("stabiliser model: " + result.reason);
          compensated = result.flow;
          compensated_homographies = std::move(result.homographies);
        } else {
          compensated = stream->compensate(flow_view, static_cast<std::int64_t>(image_a.header.stamp.toNSec()),
                                           static_cast<std::int64_t>(image_b.header.stamp.toNSec()));
        }
        ms[1] += msSince(start);
        start = Clock::now();
        auto compensated_msg = boost::make_shared<deep_ois::GyroFlow>(*gyro_msg);
        std::memcpy(compensated_msg->flow.data.data(), compensated.data, compensated_msg->flow.data.size());
        cv::Mat color, aligned, ghost;
        const sensor_msgs::ImagePtr color_msg =
            deep_ois::makeImageMsg(gyro_msg->header, sensor_msgs::image_encodings::RGB8, compensated.size(), color);
        const cv_bridge::CvImageConstPtr a = cv_bridge::toCvShare(images[k % 2]);
        const cv_bridge::CvImageConstPtr b = cv_bridge::toCvShare(images[(k + 1) % 2], sensor_msgs::image_encodings::RGB8);
        const sensor_msgs::ImagePtr aligned_msg = deep_ois::makeImageMsg(image_b.header, image_a.encoding, size, aligned);
        const sensor_msgs::ImagePtr ghost_msg =
            deep_ois::makeImageMsg(image_b.header, sensor_msgs::image_encodings::RGB8, size, ghost);
        ms[6] += msSince(start);
        start = Clock::now();
        deep_ois::colorizeFlow(compensated, params.color_max_flow_px, color);
        ms[5] += msSince(start);
        start = Clock::now();
        // As the nodelet: a stabiliser model's map straight from its homographies.
        if (stabiliser) {
          homography_builder.build(compensated_homographies, map);
        } else {
          deep_ois::buildFixedPointBackwardMap(compensated, size, 3, map);
        }
        ms[2] += msSince(start);
        start = Clock::now();
        deep_ois::warpWithFixedPointMap(a->image, map, aligned);
        ms[3] += msSince(start);
        start = Clock::now();
        deep_ois::ghostOverlay(aligned, b->image, ghost);
        ms[4] += msSince(start);

        const double chain_cpu = threadCpuMs() - cpu_start_ms;
        start = Clock::now();
        homography_builder.build(h.homographies, homography_map);
        const double homography_ms = msSince(start);
        // The yardstick: one bare remap of the same frame with the same (fixed-point) map.
        const double bare_cpu_start_ms = threadCpuMs();
        start = Clock::now();
        cv::remap(a->image, bare_out, map.xy, map.fraction, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
        const double bare = msSince(start);
        const double bare_cpu = threadCpuMs() - bare_cpu_start_ms;
        if (k < kWarmUpPairs) continue;
        if (reference_ms.size() < kReferenceRuns) {
          // What the map build replaced: the per-pixel inversion and the conversion to fixed point.
          start = Clock::now();
          cv::Mat xy, fraction;
          cv::convertMaps(deep_ois::inverseFlowMap(compensated, size, 3), cv::noArray(), xy, fraction, CV_16SC2);
          reference_ms.push_back(msSince(start));
        }
        chain_cpu_ms.push_back(chain_cpu);
        homography_map_ms.push_back(homography_ms);
        bare_remap_cpu_ms.push_back(bare_cpu);
        double chain = 0.0;
        for (int s = 0; s < 7; ++s) {
          stages[s].ms.push_back(ms[s]);
          chain += ms[s];
        }
        chain_ms.push_back(chain);
        bare_remap_ms.push_back(bare);
        one_by_one_share.push_back(static_cast<double>(map.pixels_inverted_one_by_one) / size.area());
      }
      char label[32];
      std::snprintf(label, sizeof label, "%dx%d", size.width, size.height);
      for (const Stage& stage : stages) {
        std::printf("%-10s %-20s %9.2f %9.2f %9.2f\n", label, stage.name, percentile(stage.ms, 0.5),
                    percentile(stage.ms, 0.95), mean(stage.ms));
      }
      const double fps = 1000.0 / mean(chain_ms);
      std::printf("%-10s %-20s %9.2f %9.2f %9.2f   -> %.1f frames/s\n", label, "CHAIN", percentile(chain_ms, 0.5),
                  percentile(chain_ms, 0.95), mean(chain_ms), fps);
      std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (chain / remap: %.2f at the median; %.2f %% of the pixels "
                  "inverted one by one)\n",
                  label, "bare cv::remap", percentile(bare_remap_ms, 0.5), percentile(bare_remap_ms, 0.95),
                  mean(bare_remap_ms), percentile(chain_ms, 0.5) / percentile(bare_remap_ms, 0.5),
                  100.0 * mean(one_by_one_share));
      std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (thread CPU time; bare remap %.2f, chain / remap %.2f)\n", label,
                  "CHAIN cpu", percentile(chain_cpu_ms, 0.5), percentile(chain_cpu_ms, 0.95), mean(chain_cpu_ms),
                  percentile(bare_remap_cpu_ms, 0.5), percentile(chain_cpu_ms, 0.5) / percentile(bare_remap_cpu_ms, 0.5));
      std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (PatchHomographyMapBuilder: the map from the %d patch homographies "
                  "instead of a grid flow, lattice %d px; not in the chain)\n",
                  label, "map from homographies", percentile(homography_map_ms, 0.5), percentile(homography_map_ms, 0.95),
                  mean(homography_map_ms), rs.patch_count, homography_builder.latticeStepPx());
      std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (inverseFlowMap + convertMaps, the per-pixel inversion the map "
                  "build replaced; %zu runs)\n",
                  label, "per-pixel inversion", percentile(reference_ms, 0.5), percentile(reference_ms, 0.95),
                  mean(reference_ms), reference_ms.size());
      summaries.push_back({size, fps, percentile(chain_ms, 0.5), percentile(chain_ms, 0.95),
                           percentile(bare_remap_ms, 0.5),
                           percentile(chain_ms, 0.5) / percentile(bare_remap_ms, 0.5)});
    }
    std::printf("\n| camera | chain frames/s | median ms | p95 ms | bare remap ms | chain / remap |\n");
    std::printf("|---|---:|---:|---:|---:|---:|\n");
    for (const Summary& s : summaries) {
      std::printf("| %dx%d | %.0f | %.2f | %.2f | %.2f | %.1f |\n", s.size.width, s.size.height, s.fps, s.median_ms,
                  s.p95_ms, s.remap_median_ms, s.ratio);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_compensation: %s\n", e.what());
    return 1;
  }
  return 0;
}
