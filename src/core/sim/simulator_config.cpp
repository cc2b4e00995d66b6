#include "deep_ois/core/sim/simulator_config.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace sim {

std::string SimulatorConfig::validate() const {
  const std::pair<const char*, std::string> sections[] = {
      {"sensor", sensor.validate()}, {"motion", motion.validate()}, {"ois", ois.validate()},
      {"imu", imu.validate()},       {"scene", scene.validate()}, {"lens_log", lens_log.validate()},
  };
  for (const auto& [name, problem] : sections) {
    if (!problem.empty()) return std::string(name) + ": " + problem;
  }
  const GroundTruthConfig& gt = ground_truth;
  if (gt.patch_count < 1 || gt.patch_count > sensor.height_px) {
    return "ground_truth.patch_count: must be between 1 and the image height";
  }
  if (gt.min_correspondences < 1 || gt.max_correspondences < gt.min_correspondences) {
    return "ground_truth.min_correspondences/max_correspondences: need 1 <= min <= max";
  }
  if (!(gt.lens_shift_rate_hz > 0.0)) return "ground_truth.lens_shift_rate_hz: must be positive";
  if (imu_frame_id.empty() || camera_frame_id.empty() || imu_frame_id == camera_frame_id) {
    return "frames.imu/frames.camera: must be two different, non-empty frame ids";
  }
  if (!(start_epoch_s > 0.0)) return "frames.start_epoch_s: must be positive";
  return {};
}

namespace {

// Reads one section: each known key has a setter; unknown keys are errors (a typo must not pass
// silently as a default).
class SectionReader {
 public:
  // Copy-constructed: assigning an absent section (a "zombie" node) would throw in yaml-cpp.
  SectionReader(const YAML::Node& root, const std::string& section)
      : section_(section), node_(root[section]) {
    if (node_ && !node_.IsMap()) fail("", "must be a mapping");
  }

  template <typename T>
  SectionReader& read(const std::string& key, T& value) {
    known_.push_back(key);
    if (!has(key)) return *this;
    try {
      value = section()[key].as<T>();
    } catch (const YAML::Exception&) {
      fail(key, "has the wrong type");
    }
    return *this;
  }

  SectionReader& readVector3(const std::string& key, Eigen::Vector3d& value) {
    std::vector<double> values;
    read(key, values);
    if (has(key)) {
      if (values.size() != 3) fail(key, "must hold 3 numbers");
      value = Eigen::Vector3d(values[0], values[1], values[2]);
    }
    return *this;
  }

  // An empty list (or an absent key) leaves `value` unset.
  SectionReader& readOptionalVector3(const std::string& key, std::optional<Eigen::Vector3d>& value) {
    std::vector<double> values;
    read(key, values);
    if (has(key) && !values.empty()) {
      if (values.size() != 3) fail(key, "must hold 3 numbers or none");
      value = Eigen::Vector3d(values[0], values[1], values[2]);
    }
    return *this;
  }

  SectionReader& readMatrix3(const std::string& key, Eigen::Matrix3d& value) {
    std::vector<double> values;
    read(key, values);
    if (has(key)) {
      if (values.size() != 9) fail(key, "must hold 9 numbers (row-major 3x3)");
      for (int i = 0; i < 9; ++i) value(i / 3, i % 3) = values[i];
    }
    return *this;
  }

  void finish() const {
    if (!node_) return;
    for (const auto& entry : node_) {
      const std::string key = entry.first.as<std::string>();
      if (std::find(known_.begin(), known_.end(), key) == known_.end()) fail(key, "unknown key");
    }
  }

  // Const access: yaml-cpp's non-const operator[] would insert the key it looks up.
  const YAML::Node& section() const { return node_; }
  bool has(const std::string& key) const { return node_ && section()[key]; }

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw std::runtime_error(section_ + (key.empty() ? "" : "." + key) + ": " + what);
  }

 private:
  std::string section_;
  YAML::Node node_;
  std::vector<std::string> known_;
};

}  // namespace

namespace {

// Reads `path` over `config`: keys the file holds replace the values, the others stay.
void readSimulatorConfig(const std::string& path, SimulatorConfig& config) {
  try {
    YAML::Node root;
    try {
      root = YAML::LoadFile(path);
    } catch (const YAML::BadFile&) {
      throw std::runtime_error("cannot open the file");
    } catch (const YAML::ParserException& e) {
      throw std::runtime_error(std::string("not valid YAML: ") + e.what());
    }
    if (!root.IsMap()) throw std::runtime_error("top level must be a mapping");
    static const char* kSections[] = {"category", "sensor", "motion", "ois", "imu",
                                      "scene", "ground_truth", "lens_log", "frames"};
    for (const auto& entry : root) {
      const std::string key = entry.first.as<std::string>();
      if (std::find(std::begin(kSections), std::end(kSections), key) == std::end(kSections)) {
        throw std::runtime_error(key + ": unknown section");
      }
    }
    if (root["category"]) {
      const std::string text = root["category"].as<std::string>();
      if (!parseCategory(text, &config.category)) {
        throw std::runtime_error("category: '" + text + "' is not one of RE, LT, LL, MF");
      }
    }

    SensorConfig& s = config.sensor;
    SectionReader(root, "sensor")
        .read("width_px", s.width_px)
        .read("height_px", s.height_px)
        .read("horizontal_fov_deg", s.horizontal_fov_deg)
        .read("frame_rate_hz", s.frame_rate_hz)
        .read("readout_time_s", s.readout_time_s)
        .read("exposure_time_s", s.exposure_time_s)
        .read("distortion_model", s.distortion_model)
        .read("distortion", s.distortion)
        .read("supersampling", s.supersampling)
        .read("exposure_samples", s.exposure_samples)
        .read("brightness", s.brightness)
        .read("full_well_electrons", s.full_well_electrons)
        .read("read_noise_electrons", s.read_noise_electrons)
        .read("add_noise", s.add_noise)
        .finish();

    CameraMotionConfig& m = config.motion;
    SectionReader(root, "motion")
        .read("shake_band_low_hz", m.shake_band_low_hz)
        .read("shake_band_high_hz", m.shake_band_high_hz)
        .readVector3("shake_rms_rad_s", m.shake_rms_rad_s)
        .read("shake_peak_rad_s", m.shake_peak_rad_s)
        .read("pan_peak_rad_s", m.pan_peak_rad_s)
        .read("pan_period_s", m.pan_period_s)
        .read("translation_rms_m", m.translation_rms_m)
        .read("translation_band_high_hz", m.translation_band_high_hz)
        .read("integration_rate_hz", m.integration_rate_hz)
        .finish();

    OisConfig& o = config.ois;
    std::string stroke_shape = toString(o.stroke_shape);
    SectionReader(root, "ois")
        .read("enabled", o.enabled)
        .read("highpass_corner_hz", o.highpass_corner_hz)
        .read("actuator_natural_hz", o.actuator_natural_hz)
        .read("actuator_damping", o.actuator_damping)
        .read("stroke_limit_deg", o.stroke_limit_deg)
        .read("stroke_limit_y_deg", o.stroke_limit_y_deg)
        .read("stroke_shape", stroke_shape)
        .read("gain", o.gain)
        .read("gyro_noise_rad_s", o.gyro_noise_rad_s)
        .read("control_rate_hz", o.control_rate_hz)
        .read("pan_detection_rate_rad_s", o.pan_detection_rate_rad_s)
        .read("pan_detection_time_constant_s", o.pan_detection_time_constant_s)
        .read("pan_release_corner_hz", o.pan_release_corner_hz)
        .read("hall_noise_px", o.hall_noise_px)
        .read("hall_lag_s", o.hall_lag_s)
        .read("position_loop", o.position_loop)
        .read("pi_plant_natural_hz", o.pi_plant_natural_hz)
        .read("pi_plant_damping", o.pi_plant_damping)
        .read("pi_kp", o.pi_kp)
        .read("pi_ki", o.pi_ki)
        .read("controller", o.controller)
        .read("kalman_bandwidth_hz", o.kalman_bandwidth_hz)
        .read("kalman_manoeuvre_deg", o.kalman_manoeuvre_deg)
        .read("kalman_manoeuvre_factor", o.kalman_manoeuvre_factor)
        .read("excursion_recentring_gain", o.excursion_recentring_gain)
        .read("excursion_recentring_power", o.excursion_recentring_power)
        .read("soft_stroke", o.soft_stroke)
        .read("digital_rate_hz", o.digital_rate_hz)
        .read("digital_delay_s", o.digital_delay_s)
        .read("command_lsb_deg", o.command_lsb_deg)
        .read("mount_rotation_deg", o.mount_rotation_deg)
        .read("actuator_cross_coupling", o.actuator_cross_coupling)
        .read("lens_shift_csv", o.lens_shift_csv)
        .read("design_seed", o.design_seed)
        .finish();
    if (!parseStrokeShape(stroke_shape, &o.stroke_shape)) {
      throw std::runtime_error("ois.stroke_shape: '" + stroke_shape + "' is not box or circle");
    }
    // A relative lens log path is relative to the file that names it.
    if (root["ois"] && root["ois"]["lens_shift_csv"] && !o.lens_shift_csv.empty() &&
        std::filesystem::path(o.lens_shift_csv).is_relative()) {
      o.lens_shift_csv =
          (std::filesystem::path(path).parent_path() / o.lens_shift_csv).lexically_normal().string();
    }

    ImuConfig& i = config.imu;
    SectionReader(root, "imu")
        .read("rate_hz", i.rate_hz)
        .readMatrix3("imu_to_camera_rotation", i.imu_to_camera_rotation)
        .read("gyro_noise_density", i.gyro_noise_density)
        .read("gyro_bias_random_walk", i.gyro_bias_random_walk)
        .read("gyro_initial_bias_rad_s", i.gyro_initial_bias_rad_s)
        .readOptionalVector3("gyro_initial_bias_vector_rad_s", i.gyro_initial_bias_vector_rad_s)
        .read("accel_noise_density", i.accel_noise_density)
        .read("time_offset_s", i.time_offset_s)
        .finish();

    SceneConfig& sc = config.scene;
    SectionReader(root, "scene")
        .read("texture_paths", sc.texture_paths)
        .read("near_layer_count", sc.near_layer_count)
        .read("near_depth_min_m", sc.near_depth_min_m)
        .read("near_depth_max_m", sc.near_depth_max_m)
        .read("background_depth_min_m", sc.background_depth_min_m)
        .read("background_depth_max_m", sc.background_depth_max_m)
        .read("low_texture_fraction", sc.low_texture_fraction)
        .read("moving_object_depth_m", sc.moving_object_depth_m)
        .read("moving_object_speed_m_s", sc.moving_object_speed_m_s)
        .read("moving_object_min_coverage", sc.moving_object_min_coverage)
        .finish();

    GroundTruthConfig& gt = config.ground_truth;
    SectionReader(root, "ground_truth")
        .read("patch_count", gt.patch_count)
        .read("min_correspondences", gt.min_correspondences)
        .read("max_correspondences", gt.max_correspondences)
        .read("lens_shift_rate_hz", gt.lens_shift_rate_hz)
        .finish();

    LensLogConfig& ll = config.lens_log;
    SectionReader(root, "lens_log")
        .read("enabled", ll.enabled)
        .read("rate_hz", ll.rate_hz)
        .read("latency_s", ll.latency_s)
        .read("noise_px", ll.noise_px)
        .read("quantisation", ll.quantisation)
        .read("dropout_probability", ll.dropout_probability)
        .read("gap_rate_hz", ll.gap_rate_hz)
        .read("gap_duration_s", ll.gap_duration_s)
        .read("scale", ll.convention.scale)
        .read("swap_xy", ll.convention.swap_xy)
        .read("sign_x", ll.convention.sign_x)
        .read("sign_y", ll.convention.sign_y)
        .read("time_offset_s", ll.convention.time_offset_s)
        .finish();

    SectionReader(root, "frames")
        .read("imu", config.imu_frame_id)
        .read("camera", config.camera_frame_id)
        .read("start_epoch_s", config.start_epoch_s)
        .finish();

  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

}  // namespace

SimulatorConfig loadSimulatorConfig(const std::string& path,
                                    const std::vector<std::string>& overlays) {
  SimulatorConfig config;
  readSimulatorConfig(path, config);
  for (const std::string& overlay : overlays) readSimulatorConfig(overlay, config);
  if (config.scene.texture_paths.empty()) config.scene.texture_paths = defaultTexturePaths();
  const std::string problem = config.validate();
  if (!problem.empty()) {
    std::string files = path;
    for (const std::string& overlay : overlays) files += " + " + overlay;
    throw std::runtime_error(files + ": " + problem);
  }
  return config;
}

}  // namespace sim
}  // namespace deep_ois
