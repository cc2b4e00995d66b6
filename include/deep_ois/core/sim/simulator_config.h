// Everything a simulated sequence depends on besides its seed and duration, loaded from YAML.
#pragma once

#include <string>
#include <vector>

#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/lens_log_model.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/scene.h"
#include "deep_ois/core/sim/sim_camera.h"

namespace deep_ois {
namespace sim {

struct GroundTruthConfig {
  int patch_count = 6;           // row patches of the per-pair true motion
  int min_correspondences = 6;   // annotated static-background points per pair
  int max_correspondences = 8;
  double lens_shift_rate_hz = 1000.0;  // rate of the published OIS lens shift samples
};

struct SimulatorConfig {
  Category category = Category::kRegular;
  SensorConfig sensor;
  CameraMotionConfig motion;
  OisConfig ois;
  ImuConfig imu;
  SceneConfig scene;
  GroundTruthConfig ground_truth;
  // The camera's own lens-shift log (published beside the truth; OIS cameras only).
  LensLogConfig lens_log;
  // Frame ids of the bag (the IMU and the camera optical frame).
  std::string imu_frame_id = "imu_link";
  std::string camera_frame_id = "camera_optical_frame";
  double start_epoch_s = 1700000000.0;  // ROS time of the first frame

  // Empty when usable; otherwise "section.field: problem".
  std::string validate() const;
};

// Reads a YAML file whose sections mirror SimulatorConfig (category, sensor, motion, ois, imu,
// scene, ground_truth, lens_log, frames), then each overlay file over it in order (e.g. a stabiliser module
// and a camera of config/simulator/modules/ over a category file): keys a file holds replace the
// values before it, missing keys keep them (or the defaults). Throws std::runtime_error with
// "<file>: <section.field>: <problem>" for an unknown key, a wrong type or an invalid value.
SimulatorConfig loadSimulatorConfig(const std::string& path,
                                    const std::vector<std::string>& overlays = {});

}  // namespace sim
}  // namespace deep_ois
