// One simulated sequence: motion, OIS, scene, camera, IMU and ground truth from a config, a seed
// and a duration. The same seed and config give the same sequence on any machine; a config with
// ois.enabled flipped gives its twin (same scene, motion, IMU and noise).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/ground_truth.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/rolling_shutter_renderer.h"
#include "deep_ois/core/sim/scene.h"
#include "deep_ois/core/sim/sim_camera.h"
#include "deep_ois/core/sim/simulator_config.h"

namespace deep_ois {
namespace sim {

// Simulated time before the first frame and after the last one (camera clock, seconds): the motion
// and the stabiliser start this long before the first frame, centred and at rest.
constexpr double kSimulatorMarginS = 0.25;

struct LensShiftSample {
  double stamp_s;               // camera clock
  Eigen::Vector2d shift_px;     // principal-point shift, pixels
};

class Simulator {
 public:
  // Throws std::invalid_argument naming the problem for a bad config or duration, and
  // std::runtime_error when a texture cannot be read.
  Simulator(const SimulatorConfig& config, std::uint32_t seed, double duration_s);

  const SimulatorConfig& config() const { return config_; }
  std::uint32_t seed() const { return seed_; }
  int frameCount() const { return frame_count_; }
  // Camera-clock stamp of frame k, seconds since the first frame (k / frame rate).
  double frameStamp(int k) const;
  cv::Mat renderFrame(int k) const;
  // Ground truth of frames k-1 -> k (k >= 1).
  FramePairTruth pairTruth(int k) const;
  // IMU samples covering every frame pair with margin (IMU clock).
  const std::vector<ImuMeasurement>& imu() const { return imu_; }
  std::vector<LensShiftSample> lensShiftSamples() const;
  // The camera's own lens-shift log (config.lens_log) over the same span as lensShiftSamples;
  // empty for a camera without OIS or with lens_log.enabled false. The same seed gives the same
  // log; a twin with OIS off has none.
  std::vector<LoggedLensSample> lensShiftLog() const;

  const SimCamera& camera() const { return *camera_; }
  const Scene& scene() const { return scene_; }

 private:
  // Independent streams per component, so that changing one (e.g. the OIS) leaves the others.
  std::uint32_t subSeed(std::uint32_t stream) const;

  SimulatorConfig config_;
  std::uint32_t seed_;
  int frame_count_;
  double start_s_, end_s_;  // simulated time span (camera clock), frames plus margin
  std::unique_ptr<CameraMotion> motion_;
  std::unique_ptr<OisModel> ois_;
  std::unique_ptr<SimCamera> camera_;
  Scene scene_;
  std::unique_ptr<RollingShutterRenderer> renderer_;
  std::vector<ImuMeasurement> imu_;
};

}  // namespace sim
}  // namespace deep_ois
