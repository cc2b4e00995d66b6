// Fixtures shared by the simulator gtests.
#pragma once

#include <cstdint>

#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/sim_camera.h"

namespace deep_ois {
namespace test {

// A camera that does not move at all.
inline sim::CameraMotionConfig stillMotionConfig() {
  sim::CameraMotionConfig config;
  config.shake_rms_rad_s.setZero();
  config.pan_peak_rad_s = 0.0;
  config.translation_rms_m = 0.0;
  return config;
}

// Hand-held motion (the default shake and pans) over [start_s, end_s], an OIS and a camera.
struct Rig {
  Rig(double start_s, double end_s, const sim::SensorConfig& sensor_config, std::uint32_t seed,
      const sim::OisConfig& ois_config = sim::OisConfig())
      : sensor(sensor_config),
        motion(sim::CameraMotionConfig(), seed, start_s, end_s),
        ois(ois_config, motion, sim::nominalCamera(sensor).K()(0, 0), seed),
        camera(sensor, motion, ois) {}
  double focalPx() const { return camera.nominal().K()(0, 0); }

  sim::SensorConfig sensor;
  sim::CameraMotion motion;
  sim::OisModel ois;
  sim::SimCamera camera;
};

}  // namespace test
}  // namespace deep_ois
