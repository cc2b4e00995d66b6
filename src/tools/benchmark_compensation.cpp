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
#include "deep_ois/core/flow/patch_homography_map.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
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

// The stages of the chain, in the order they are printed (docs/benchmarks.md).
enum StageIndex { kGyroFlow, kInference, kMapBuild, kRemap, kGhost, kColour, kMessages, kStageCount };

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

std::vector<cv::Size> parseSizes(const std::string& text) {
  std::vector<cv::Size> sizes;
  std::stringstream list(text);
  for (std::string item; std::getline(list, item, ',');) sizes.push_back(parseSize(item));
  return sizes;
}

struct BenchmarkFlags {
  std::string model_path;
  std::string sizes_text = "256x192,640x480,1280x720,1920x1080";
  int torch_threads = 1, warp_threads = 1, frames = 200;
};

void addFlags(deep_ois::ToolCommandLine& command_line, BenchmarkFlags& flags) {
  CLI::App& app = command_line.app();
  app.add_option("--model", flags.model_path, "the compensation model: a stabiliser model .yaml or a network .pt")
      ->check(deep_ois::existingFile())
      ->capture_default_str()
      ->type_name("FILE");
  command_line.addNumber("--frames", flags.frames, "frame pairs timed per camera size (>= 10)")
      ->check(CLI::Range(10, 1000000));
  command_line.addNumber("--threads", flags.torch_threads, "torch intra-op threads (>= 1)")
      ->check(CLI::Range(1, 256));
  command_line.addNumber("--warp-threads", flags.warp_threads, "OpenCV threads of the warp (>= 1)")
      ->check(CLI::Range(1, 256));
  app.add_option("--sizes", flags.sizes_text, "camera sizes, comma-separated WIDTHxHEIGHT")
      ->capture_default_str()
      ->type_name("WxH,...");
}

// The compensation model, as the nodelet's ~model: a learned stabiliser model (.yaml) or the
// network (.pt).
struct LoadedModel {
  std::unique_ptr<deep_ois::CompensationModel> network;
  std::unique_ptr<deep_ois::StabiliserModelFile> stabiliser;
};

LoadedModel loadModel(const std::string& path) {
  LoadedModel model;
  if (deep_ois::isStabiliserModelPath(path)) {
    model.stabiliser = std::make_unique<deep_ois::StabiliserModelFile>(deep_ois::StabiliserModelFile::load(path));
  } else {
    model.network = std::make_unique<deep_ois::CompensationModel>(deep_ois::CompensationModel::load(path));
  }
  return model;
}

void printSetup(const BenchmarkFlags& flags, const LoadedModel& model, const deep_ois::GyroFlowParameters& params) {
  if (model.stabiliser) {
    std::printf("benchmark_compensation: learned stabiliser model %s, flow grid %dx%d, %d OpenCV thread(s), %d "
                "frame pairs per size, %u hardware threads\n",
                flags.model_path.c_str(), params.grid_size.width, params.grid_size.height, flags.warp_threads,
                flags.frames, std::thread::hardware_concurrency());
  } else {
    const auto& m = model.network->metadata();
    std::printf("benchmark_compensation: model %s (preset %s, network grid %dx%d), flow grid %dx%d, %d torch "
                "thread(s), %d OpenCV thread(s), %d frame pairs per size, %u hardware threads\n",
                flags.model_path.c_str(), m.preset.c_str(), m.working_grid.width, m.working_grid.height,
                params.grid_size.width, params.grid_size.height, flags.torch_threads, flags.warp_threads,
                flags.frames, std::thread::hardware_concurrency());
  }
}

// The synthetic gyro, shared by all sizes: 400 Hz over the whole run.
deep_ois::ImuSampleBuffer syntheticGyro(int frames) {
  const double duration_s = (frames + kWarmUpPairs + 12) * kFramePeriodS + 1.0;
  deep_ois::ImuSampleBuffer imu(duration_s + 1.0);
  for (double t = 0.0; t <= duration_s; t += 1.0 / kImuRateHz) imu.add({t, angularVelocity(t)});
  return imu;
}

// The timed pairs of one camera size (after the warm-up).
struct SizeTimings {
  std::vector<Stage> stages = {{"gyro flow", {}}, {"inference", {}},      {"map build", {}},
                               {"remap", {}},     {"ghost", {}},          {"colour", {}},
                               {"message conversion", {}}};
  std::vector<double> chain_ms, bare_remap_ms, one_by_one_share, chain_cpu_ms, bare_remap_cpu_ms, reference_ms;
  std::vector<double> homography_map_ms;
};

struct Summary {
  cv::Size size;
  double fps, median_ms, p95_ms, remap_median_ms, ratio;
};

// Both live nodelets' per-frame work at one camera size, with the same core calls as the
// nodelets: the gyro flow nodelet, then the compensation nodelet with every output subscribed
// (CompensationRos::process); beside it, the yardsticks (a bare remap, the map from the patch
// homographies, the per-pixel inversion).
class FramePairChain {
 public:
  FramePairChain(cv::Size size, const LoadedModel& model, const deep_ois::GyroFlowParameters& params,
                 const deep_ois::ImuSampleBuffer& imu)
      : size_(size),
        params_(params),
        imu_(imu),
        camera_(cameraOfSize(size)),
        rs_(rollingShutter(params)),
        homography_builder_(camera_, rs_.patch_count),
        images_{texturedFrame(size, 1, kBase), texturedFrame(size, 2, kBase)} {
    if (model.stabiliser) {
      stabiliser_compensator_ = std::make_unique<deep_ois::StabiliserFlowCompensator>(*model.stabiliser);
    } else {
      stream_ = std::make_unique<deep_ois::CompensationStream>(*model.network);
    }
    metadata_.camera = camera_;
    metadata_.distortion_model = "plumb_bob";
    metadata_.rolling_shutter = rs_;
    metadata_.header.frame_id = "camera";
  }

  // Frame pair k: timed, and recorded in `timings` after the warm-up pairs.
  void run(int k, SizeTimings& timings) {
    const double stamp_a_s = 0.5 + k * kFramePeriodS, stamp_b_s = stamp_a_s + kFramePeriodS;
    sensor_msgs::Image& image_a = *images_[k % 2];
    sensor_msgs::Image& image_b = *images_[(k + 1) % 2];
    image_a.header.stamp = kBase + ros::Duration(stamp_a_s);
    image_b.header.stamp = kBase + ros::Duration(stamp_b_s);
    double ms[kStageCount] = {0, 0, 0, 0, 0, 0, 0};
    const double cpu_start_ms = threadCpuMs();
    std::vector<Eigen::Matrix3d> gyro_homographies;
    const boost::shared_ptr<deep_ois::GyroFlow> gyro_msg = gyroFlowNodelet(k, stamp_a_s, stamp_b_s, gyro_homographies, ms);
    const cv::Mat compensated = compensationNodelet(k, *gyro_msg, ms);
    const double chain_cpu = threadCpuMs() - cpu_start_ms;
    const Yardsticks yardsticks = timeYardsticks(gyro_homographies);
    if (k < kWarmUpPairs) return;
    if (timings.reference_ms.size() < kReferenceRuns) {
      // What the map build replaced: the per-pixel inversion and the conversion to fixed point.
      const auto start = Clock::now();
      cv::Mat xy, fraction;
      cv::convertMaps(deep_ois::inverseFlowMap(compensated, size_, 3), cv::noArray(), xy, fraction, CV_16SC2);
      timings.reference_ms.push_back(msSince(start));
    }
    timings.chain_cpu_ms.push_back(chain_cpu);
    timings.homography_map_ms.push_back(yardsticks.homography_map_ms);
    timings.bare_remap_cpu_ms.push_back(yardsticks.bare_remap_cpu_ms);
    double chain = 0.0;
    for (int s = 0; s < kStageCount; ++s) {
      timings.stages[s].ms.push_back(ms[s]);
      chain += ms[s];
    }
    timings.chain_ms.push_back(chain);
    timings.bare_remap_ms.push_back(yardsticks.bare_remap_ms);
    timings.one_by_one_share.push_back(static_cast<double>(map_.pixels_inverted_one_by_one) / size_.area());
  }

  int patchCount() const { return rs_.patch_count; }
  int latticeStepPx() const { return homography_builder_.latticeStepPx(); }

 private:
  struct Yardsticks {
    double homography_map_ms, bare_remap_ms, bare_remap_cpu_ms;
  };
  static const ros::Time kBase;

  static deep_ois::RollingShutterConfig rollingShutter(const deep_ois::GyroFlowParameters& params) {
    deep_ois::RollingShutterConfig rs = params.rolling_shutter;
    rs.imu_to_camera_rotation = Eigen::Matrix3d::Identity();
    return rs;
  }

  // Gyro flow nodelet: homographies, the flow on the grid (the frame-pair processor without a lens,
  // as GyroFlowRos), its message and colour image.
  boost::shared_ptr<deep_ois::GyroFlow> gyroFlowNodelet(int k, double stamp_a_s, double stamp_b_s,
                                                        std::vector<Eigen::Matrix3d>& homographies, double* ms) {
    const sensor_msgs::Image& image_a = *images_[k % 2];
    const sensor_msgs::Image& image_b = *images_[(k + 1) % 2];
    auto start = Clock::now();
    deep_ois::FramePair pair;
    pair.stamp_a_s = stamp_a_s;
    pair.stamp_b_s = stamp_b_s;
    pair.timing = rs_;
    pair.camera = &camera_;
    pair.imu = &imu_;
    pair.integration = params_.integration;
    deep_ois::FramePairMotion motion = gyro_flow_processor_.process(std::move(pair), params_.grid_size);
    if (!motion.ok) throw std::runtime_error("synthetic gyro does not cover frame pair " + std::to_string(k));
    homographies = std::move(motion.homographies);
    gyro_flow_ = motion.flow;
    ms[kGyroFlow] += msSince(start);
    start = Clock::now();
    metadata_.header.stamp = image_b.header.stamp;
    metadata_.previous_stamp = image_a.header.stamp;
    // The gyro stream the message carries (as gyro_flow_ros), relative to frame b's stamp.
    metadata_.camera_rates.clear();
    for (deep_ois::CameraRateSample rate : deep_ois::pairGyroStream(imu_, rs_, stamp_a_s, stamp_b_s)) {
      rate.stamp_s -= stamp_b_s;
      metadata_.camera_rates.push_back(rate);
    }
    auto gyro_msg = boost::make_shared<deep_ois::GyroFlow>();
    deep_ois::fillGyroFlowMsg(metadata_, homographies, gyro_flow_, *gyro_msg);
    cv::Mat gyro_color;
    const sensor_msgs::ImagePtr gyro_color_msg =
        deep_ois::makeImageMsg(gyro_msg->header, sensor_msgs::image_encodings::RGB8, gyro_flow_.size(), gyro_color);
    ms[kMessages] += msSince(start);
    start = Clock::now();
    deep_ois::colorizeFlow(gyro_flow_, params_.color_max_flow_px, gyro_color);
    ms[kColour] += msSince(start);
    return gyro_msg;
  }

  // Compensation nodelet, every output subscribed (CompensationRos::process). Returns the
  // compensated flow; leaves the map the warp used in map_.
  cv::Mat compensationNodelet(int k, const deep_ois::GyroFlow& gyro_msg, double* ms) {
    const sensor_msgs::Image& image_a = *images_[k % 2];
    const sensor_msgs::Image& image_b = *images_[(k + 1) % 2];
    auto start = Clock::now();
    std::vector<Eigen::Matrix3d> homographies;
    cv::Mat flow_view;
    const std::string problem = deep_ois::readGyroFlowMsg(gyro_msg, homographies, flow_view);
    if (!problem.empty()) throw std::runtime_error(problem);
    ms[kMessages] += msSince(start);
    start = Clock::now();
    cv::Mat compensated;
    std::vector<Eigen::Matrix3d> compensated_homographies;  // a stabiliser model's
    if (stabiliser_compensator_) {
      deep_ois::StabiliserFlowResult result = stabiliser_compensator_->compensate(gyro_msg);
      if (!result.ok) throw std::runtime_error("stabiliser model: " + result.reason);
      compensated = result.flow;
      compensated_homographies = std::move(result.homographies);
    } else {
      compensated = stream_->compensate(flow_view, static_cast<std::int64_t>(image_a.header.stamp.toNSec()),
                                        static_cast<std::int64_t>(image_b.header.stamp.toNSec()));
    }
    ms[kInference] += msSince(start);
    start = Clock::now();
    auto compensated_msg = boost::make_shared<deep_ois::GyroFlow>(gyro_msg);
    std::memcpy(compensated_msg->flow.data.data(), compensated.data, compensated_msg->flow.data.size());
    cv::Mat color, aligned, ghost;
    const sensor_msgs::ImagePtr color_msg =
        deep_ois::makeImageMsg(gyro_msg.header, sensor_msgs::image_encodings::RGB8, compensated.size(), color);
    a_ = cv_bridge::toCvShare(images_[k % 2]);
    const cv_bridge::CvImageConstPtr b = cv_bridge::toCvShare(images_[(k + 1) % 2], sensor_msgs::image_encodings::RGB8);
    const sensor_msgs::ImagePtr aligned_msg = deep_ois::makeImageMsg(image_b.header, image_a.encoding, size_, aligned);
    const sensor_msgs::ImagePtr ghost_msg =
        deep_ois::makeImageMsg(image_b.header, sensor_msgs::image_encodings::RGB8, size_, ghost);
    ms[kMessages] += msSince(start);
    start = Clock::now();
    deep_ois::colorizeFlow(compensated, params_.color_max_flow_px, color);
    ms[kColour] += msSince(start);
    start = Clock::now();
    // As the nodelet: a stabiliser model's map straight from its homographies.
    if (stabiliser_compensator_) {
      homography_builder_.build(compensated_homographies, map_);
    } else {
      deep_ois::buildFixedPointBackwardMap(compensated, size_, 3, map_);
    }
    ms[kMapBuild] += msSince(start);
    start = Clock::now();
    deep_ois::warpWithFixedPointMap(a_->image, map_, aligned);
    ms[kRemap] += msSince(start);
    start = Clock::now();
    deep_ois::ghostOverlay(aligned, b->image, ghost);
    ms[kGhost] += msSince(start);
    return compensated;
  }

  // Beside the chain, not in it: the map straight from the six row-patch homographies (what a
  // compensator that outputs homographies warps by), and one bare remap of the same frame with
  // the same (fixed-point) map.
  Yardsticks timeYardsticks(const std::vector<Eigen::Matrix3d>& gyro_homographies) {
    Yardsticks yardsticks;
    auto start = Clock::now();
    homography_builder_.build(gyro_homographies, homography_map_);
    yardsticks.homography_map_ms = msSince(start);
    const double bare_cpu_start_ms = threadCpuMs();
    start = Clock::now();
    cv::remap(a_->image, bare_out_, map_.xy, map_.fraction, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    yardsticks.bare_remap_ms = msSince(start);
    yardsticks.bare_remap_cpu_ms = threadCpuMs() - bare_cpu_start_ms;
    return yardsticks;
  }

  const cv::Size size_;
  const deep_ois::GyroFlowParameters& params_;
  const deep_ois::ImuSampleBuffer& imu_;
  const deep_ois::CameraModel camera_;
  const deep_ois::RollingShutterConfig rs_;
  deep_ois::FramePairProcessor gyro_flow_processor_;  // the gyro flow nodelet's: no lens
  const deep_ois::PatchHomographyMapBuilder homography_builder_;
  std::unique_ptr<deep_ois::CompensationStream> stream_;
  std::unique_ptr<deep_ois::StabiliserFlowCompensator> stabiliser_compensator_;
  deep_ois::GyroFlowMetadata metadata_;
  const sensor_msgs::ImagePtr images_[2];
  deep_ois::FixedPointMap map_, homography_map_;
  cv_bridge::CvImageConstPtr a_;  // frame a of the current pair, as the compensation reads it
  cv::Mat gyro_flow_, bare_out_;
};

const ros::Time FramePairChain::kBase(1000.0);

// The stage table of one camera size, its chain against the yardsticks; the size's summary row.
Summary printSizeTimings(cv::Size size, const SizeTimings& t, const FramePairChain& chain) {
  char label[32];
  std::snprintf(label, sizeof label, "%dx%d", size.width, size.height);
  for (const Stage& stage : t.stages) {
    std::printf("%-10s %-20s %9.2f %9.2f %9.2f\n", label, stage.name, percentile(stage.ms, 0.5),
                percentile(stage.ms, 0.95), mean(stage.ms));
  }
  const double fps = 1000.0 / mean(t.chain_ms);
  std::printf("%-10s %-20s %9.2f %9.2f %9.2f   -> %.1f frames/s\n", label, "CHAIN", percentile(t.chain_ms, 0.5),
              percentile(t.chain_ms, 0.95), mean(t.chain_ms), fps);
  std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (chain / remap: %.2f at the median; %.2f %% of the pixels "
              "inverted one by one)\n",
              label, "bare cv::remap", percentile(t.bare_remap_ms, 0.5), percentile(t.bare_remap_ms, 0.95),
              mean(t.bare_remap_ms), percentile(t.chain_ms, 0.5) / percentile(t.bare_remap_ms, 0.5),
              100.0 * mean(t.one_by_one_share));
  std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (thread CPU time; bare remap %.2f, chain / remap %.2f)\n", label,
              "CHAIN cpu", percentile(t.chain_cpu_ms, 0.5), percentile(t.chain_cpu_ms, 0.95), mean(t.chain_cpu_ms),
              percentile(t.bare_remap_cpu_ms, 0.5), percentile(t.chain_cpu_ms, 0.5) / percentile(t.bare_remap_cpu_ms, 0.5));
  std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (PatchHomographyMapBuilder: the map from the %d patch homographies "
              "instead of a grid flow, lattice %d px; not in the chain)\n",
              label, "map from homographies", percentile(t.homography_map_ms, 0.5),
              percentile(t.homography_map_ms, 0.95), mean(t.homography_map_ms), chain.patchCount(),
              chain.latticeStepPx());
  std::printf("%-10s %-20s %9.2f %9.2f %9.2f   (inverseFlowMap + convertMaps, the per-pixel inversion the map "
              "build replaced; %zu runs)\n",
              label, "per-pixel inversion", percentile(t.reference_ms, 0.5), percentile(t.reference_ms, 0.95),
              mean(t.reference_ms), t.reference_ms.size());
  return {size, fps, percentile(t.chain_ms, 0.5), percentile(t.chain_ms, 0.95), percentile(t.bare_remap_ms, 0.5),
          percentile(t.chain_ms, 0.5) / percentile(t.bare_remap_ms, 0.5)};
}

void printSummaryTable(const std::vector<Summary>& summaries) {
  std::printf("\n| camera | chain frames/s | median ms | p95 ms | bare remap ms | chain / remap |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (const Summary& s : summaries) {
    std::printf("| %dx%d | %.0f | %.2f | %.2f | %.2f | %.1f |\n", s.size.width, s.size.height, s.fps, s.median_ms,
                s.p95_ms, s.remap_median_ms, s.ratio);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string package = ros::package::getPath("deep_ois");
  BenchmarkFlags flags;
  // The launch files' default (launch/deep_ois.launch): what a user runs is what is timed.
  flags.model_path = package + "/models/stabiliser_generic.yaml";
  deep_ois::ToolCommandLine command_line(
      "benchmark_compensation",
      "Times both live nodelets' per-frame work at robot camera resolutions, per stage, on "
      "synthetic frames and a synthetic hand-held gyro, with a bare cv::remap of the same frame as "
      "the yardstick (docs/benchmarks.md). One core by default.",
      "Exit status: 0 done, 1 failed, 2 usage.");
  addFlags(command_line, flags);
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    if (flags.frames < 10 || flags.torch_threads < 1 || flags.warp_threads < 1)
      throw std::invalid_argument("--frames >= 10, threads >= 1");
    const std::vector<cv::Size> sizes = parseSizes(flags.sizes_text);
    cv::setNumThreads(flags.warp_threads);  // as the nodelet's ~warp_threads
    deep_ois::setTorchThreads(flags.torch_threads);
    const LoadedModel model = loadModel(flags.model_path);
    const deep_ois::GyroFlowParameters params =
        deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(package + "/config/gyro_flow.yaml"));
    printSetup(flags, model, params);
    const deep_ois::ImuSampleBuffer imu = syntheticGyro(flags.frames);

    std::printf("\n%-10s %-20s %9s %9s %9s\n", "camera", "stage", "median ms", "p95 ms", "mean ms");
    std::vector<Summary> summaries;
    for (const cv::Size size : sizes) {
      FramePairChain chain(size, model, params, imu);
      SizeTimings timings;
      for (int k = 0; k < flags.frames + kWarmUpPairs; ++k) chain.run(k, timings);
      summaries.push_back(printSizeTimings(size, timings, chain));
    }
    printSummaryTable(summaries);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_compensation: %s\n", e.what());
    return 1;
  }
  return 0;
}
