// Renders frames of the simulated camera: every row at its own time and pose, anti-aliased by
// supersampling, motion-blurred over the exposure, with sensor noise.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

#include "deep_ois/core/sim/scene.h"
#include "deep_ois/core/sim/sim_camera.h"

namespace deep_ois {
namespace sim {

class RollingShutterRenderer {
 public:
  // Keeps references: scene and camera must outlive the renderer.
  RollingShutterRenderer(const Scene& scene, const SimCamera& camera);

  // The frame stamped `stamp_s` (mid-exposure of its first row), CV_8UC3 RGB. Noise is drawn
  // from (noise_seed, frame_index), so a frame is reproducible on its own.
  cv::Mat render(double stamp_s, std::uint64_t frame_index, std::uint32_t noise_seed) const;

 private:
  const Scene& scene_;
  const SimCamera& camera_;
};

}  // namespace sim
}  // namespace deep_ois
