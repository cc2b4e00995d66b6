#include "deep_ois/core/sim/simulator.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

Simulator::Simulator(const SimulatorConfig& config, std::uint32_t seed, double duration_s)
    : config_(config), seed_(seed) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("simulator config: " + problem);
  if (!(duration_s > 0.0) || duration_s > 3600.0) {
    throw std::invalid_argument("duration must be between 0 and 3600 s");
  }
  const SensorConfig& sensor = config_.sensor;
  frame_count_ = static_cast<int>(std::floor(duration_s * sensor.frame_rate_hz)) + 1;
  if (frame_count_ < 2) throw std::invalid_argument("duration must cover at least two frames");
  start_s_ = -kSimulatorMarginS;
  end_s_ = frameStamp(frame_count_ - 1) + sensor.readout_time_s + sensor.exposure_time_s + kSimulatorMarginS;

  motion_ = std::make_unique<CameraMotion>(config_.motion, subSeed(1), start_s_, end_s_);
  const double focal_px = nominalCamera(sensor).K()(0, 0);
  ois_ = std::make_unique<OisModel>(config_.ois, *motion_, focal_px, subSeed(2));
  camera_ = std::make_unique<SimCamera>(sensor, *motion_, *ois_);
  scene_ = buildScene(config_.scene, config_.category, subSeed(3), *motion_, focal_px, sensor.supersampling);
  renderer_ = std::make_unique<RollingShutterRenderer>(scene_, *camera_);
  // IMU from 0.1 s before the first frame to 0.1 s after the last row of the last frame.
  imu_ = sampleImu(config_.imu, *motion_, subSeed(4), -0.1,
                   frameStamp(frame_count_ - 1) + sensor.readout_time_s + 0.1);
}

std::uint32_t Simulator::subSeed(std::uint32_t stream) const { return streamSeed(seed_, stream); }

double Simulator::frameStamp(int k) const { return k / config_.sensor.frame_rate_hz; }

cv::Mat Simulator::renderFrame(int k) const {
  return renderer_->render(frameStamp(k), static_cast<std::uint64_t>(k), subSeed(5));
}

FramePairTruth Simulator::pairTruth(int k) const {
  if (k < 1 || k >= frame_count_) {
    std::ostringstream why;
    why << "pairTruth: frame " << k << " has no predecessor in 0.." << frame_count_ - 1;
    throw std::out_of_range(why.str());
  }
  return computeFramePairTruth(*camera_, scene_, frameStamp(k - 1), frameStamp(k), config_.ground_truth,
                               subSeed(1000u + static_cast<std::uint32_t>(k)));
}

std::vector<LensShiftSample> Simulator::lensShiftSamples() const {
  std::vector<LensShiftSample> samples;
  const double dt = 1.0 / config_.ground_truth.lens_shift_rate_hz;
  const double end = frameStamp(frame_count_ - 1) + config_.sensor.readout_time_s + config_.sensor.exposure_time_s;
  for (int k = 0;; ++k) {
    const double t = -0.05 + k * dt;
    if (t > end) break;
    samples.push_back({t, ois_->lensShift(t)});
  }
  return samples;
}

std::vector<LoggedLensSample> Simulator::lensShiftLog() const {
  if (!config_.ois.enabled || !config_.lens_log.enabled) return {};
  const double end = frameStamp(frame_count_ - 1) + config_.sensor.readout_time_s + config_.sensor.exposure_time_s;
  return simulateLensLog(config_.lens_log, [this](double t) { return ois_->lensShift(t); }, -0.05, end, subSeed(6));
}

}  // namespace sim
}  // namespace deep_ois
