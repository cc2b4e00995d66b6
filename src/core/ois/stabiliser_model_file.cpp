#include "deep_ois/core/ois/stabiliser_model_file.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/camera/camera_description_yaml.h"

namespace deep_ois {
namespace {

constexpr const char* kFormatName = "deep_ois_stabiliser_model";

// Why the model cannot be written beside `path` (the file is created in the target's folder, then
// renamed): names the folder, since a mistyped --out folder is the usual cause, and the system's
// reason (`error`, the errno of the failed open).
std::string whyNotWritable(const std::string& path, int error) {
  std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (parent.empty()) parent = ".";
  const std::string folder = parent.string();
  std::error_code ignored;
  std::string problem;
  if (!std::filesystem::exists(parent, ignored))
    problem = "the folder " + folder + " does not exist";
  else if (!std::filesystem::is_directory(parent, ignored))
    problem = folder + " is not a folder";
  else
    problem = "cannot create a file in the folder " + folder;
  return "cannot write the stabiliser model: " + problem + " (" + std::strerror(error) + ")";
}

// The complete file written beside `path` and renamed onto it (per process: two writers of the
// same model do not write into one partial file).
std::string partialPathFor(const std::string& path) {
  return path + ".partial." + std::to_string(::getpid());
}

template <typename T>
T required(const YAML::Node& node, const std::string& key) {
  if (!node[key]) throw StabiliserModelFileError("missing field '" + key + "'");
  try {
    return node[key].as<T>();
  } catch (const YAML::Exception&) {
    throw StabiliserModelFileError("field '" + key + "' is malformed");
  }
}

template <typename T>
T optional(const YAML::Node& node, const std::string& key, T fallback) {
  return node[key] ? required<T>(node, key) : fallback;
}

}  // namespace

bool isStabiliserModelPath(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos) return false;
  const std::string ext = path.substr(dot);
  return ext == ".yaml" || ext == ".yml";
}

std::string StabiliserModelFile::toYaml() const {
  YAML::Emitter out;
  out.SetDoublePrecision(10);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormatName;
  out << YAML::Key << "format_version" << YAML::Value << format_version;
  out << YAML::Key << "name" << YAML::Value << name;
  const StabiliserParameters& p = parameters;
  out << YAML::Key << "stabiliser" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "gain" << YAML::Value << YAML::Flow
      << std::vector<double>{p.gain(0, 0), p.gain(0, 1), p.gain(1, 0), p.gain(1, 1)};
  out << YAML::Key << "highpass_corner_hz" << YAML::Value << p.highpass_corner_hz;
  out << YAML::Key << "actuator_natural_hz" << YAML::Value << p.actuator_natural_hz;
  out << YAML::Key << "actuator_damping" << YAML::Value << p.actuator_damping;
  out << YAML::Key << "sensor_lag_s" << YAML::Value << p.sensor_lag_s;
  out << YAML::Key << "stroke_x_deg" << YAML::Value << p.stroke_x_deg;
  out << YAML::Key << "stroke_y_deg" << YAML::Value << p.stroke_y_deg;
  out << YAML::Key << "circular_stroke" << YAML::Value << p.circular_stroke;
  // Optional (written only when used): files without them, every model before these mechanisms,
  // load as a winding-up integrator with a fixed corner and an end stop.
  if (p.soft_stroke) out << YAML::Key << "soft_stroke" << YAML::Value << p.soft_stroke;
  if (p.anti_windup) out << YAML::Key << "anti_windup" << YAML::Value << p.anti_windup;
  if (p.excursion_centring != 0.0)
    out << YAML::Key << "excursion_centring" << YAML::Value << p.excursion_centring;
  if (!p.actuator_coupling.isZero(0.0))
    out << YAML::Key << "actuator_coupling" << YAML::Value << YAML::Flow
        << std::vector<double>{p.actuator_coupling.x(), p.actuator_coupling.y()};
  out << YAML::Key << "pan_detection_rate_rad_s" << YAML::Value << p.pan_detection_rate_rad_s;
  out << YAML::Key << "pan_detection_time_constant_s" << YAML::Value
      << p.pan_detection_time_constant_s;
  out << YAML::Key << "pan_release_corner_hz" << YAML::Value << p.pan_release_corner_hz;
  out << YAML::Key << "residual_time_constants_s" << YAML::Value << YAML::Flow
      << p.residual_time_constants_s;
  std::vector<double> residual;
  for (long r = 0; r < p.residual.rows(); ++r)
    for (long c = 0; c < p.residual.cols(); ++c) residual.push_back(p.residual(r, c));
  out << YAML::Key << "residual" << YAML::Value << YAML::Flow << residual;
  if (!p.nonlinear_features.empty()) {
    // Optional: files without it (every model before the learned nonlinear residual) still load.
    out << YAML::Key << "nonlinear_features" << YAML::Value << p.nonlinear_features;
    std::vector<double> nonlinear;
    for (long r = 0; r < p.nonlinear_residual.rows(); ++r)
      for (long c = 0; c < p.nonlinear_residual.cols(); ++c)
        nonlinear.push_back(p.nonlinear_residual(r, c));
    out << YAML::Key << "nonlinear_residual" << YAML::Value << YAML::Flow << nonlinear;
  }
  if (p.learned_dynamics.active()) {
    // Optional: the generic learned stage, its network embedded (the file stands alone).
    const LearnedLensDynamics& learned = p.learned_dynamics;
    out << YAML::Key << "learned_dynamics" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "conditioning" << YAML::Value << YAML::Flow
        << std::vector<double>(learned.conditioning.data(),
                               learned.conditioning.data() + learned.conditioning.size());
    out << YAML::Key << "output_map" << YAML::Value << YAML::Flow
        << std::vector<double>{learned.output_map(0, 0), learned.output_map(0, 1),
                               learned.output_map(1, 0), learned.output_map(1, 1)};
    out << YAML::Key << "network" << YAML::Value;
    writeLensDynamicsNetwork(out, *learned.network);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  writeCameraDescription(out, camera);
  const StabiliserTrainingRecord& t = training;
  out << YAML::Key << "training" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "target" << YAML::Value << t.target;
  out << YAML::Key << "data_files" << YAML::Value << t.data_files;
  out << YAML::Key << "data_sha256" << YAML::Value << t.data_sha256;
  out << YAML::Key << "recordings" << YAML::Value << t.recordings;
  out << YAML::Key << "observations" << YAML::Value << t.observations;
  out << YAML::Key << "rms_without_model_px" << YAML::Value << t.rms_without_model_px;
  out << YAML::Key << "rms_px" << YAML::Value << t.rms_px;
  out << YAML::Key << "held_out_rms_without_model_px" << YAML::Value
      << t.held_out_rms_without_model_px;
  out << YAML::Key << "held_out_rms_px" << YAML::Value << t.held_out_rms_px;
  out << YAML::Key << "training_time_s" << YAML::Value << t.training_time_s;
  out << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

StabiliserModelFile StabiliserModelFile::fromYaml(const std::string& yaml_text) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw StabiliserModelFileError(std::string("not YAML: ") + e.what());
  }
  if (!root.IsMap() || optional<std::string>(root, "format", "") != kFormatName)
    throw StabiliserModelFileError(std::string("not a stabiliser model (format: ") + kFormatName +
                                   " missing)");
  StabiliserModelFile file;
  file.format_version = required<int>(root, "format_version");
  if (file.format_version != kFormatVersion)
    throw StabiliserModelFileError("format_version " + std::to_string(file.format_version) +
                                   " is not supported (this build reads " +
                                   std::to_string(kFormatVersion) + ")");
  file.name = optional<std::string>(root, "name", "");
  if (!root["stabiliser"]) throw StabiliserModelFileError("missing section 'stabiliser'");
  const YAML::Node s = root["stabiliser"];
  StabiliserParameters& p = file.parameters;
  const auto gain = required<std::vector<double>>(s, "gain");
  if (gain.size() != 4) throw StabiliserModelFileError("field 'gain' must have 4 values");
  p.gain << gain[0], gain[1], gain[2], gain[3];
  p.highpass_corner_hz = required<double>(s, "highpass_corner_hz");
  p.actuator_natural_hz = required<double>(s, "actuator_natural_hz");
  p.actuator_damping = required<double>(s, "actuator_damping");
  p.sensor_lag_s = required<double>(s, "sensor_lag_s");
  p.stroke_x_deg = required<double>(s, "stroke_x_deg");
  p.stroke_y_deg = required<double>(s, "stroke_y_deg");
  p.circular_stroke = required<bool>(s, "circular_stroke");
  p.soft_stroke = optional<bool>(s, "soft_stroke", false);
  p.anti_windup = optional<bool>(s, "anti_windup", false);
  p.excursion_centring = optional<double>(s, "excursion_centring", 0.0);
  const auto coupling = optional<std::vector<double>>(s, "actuator_coupling", {0.0, 0.0});
  if (coupling.size() != 2)
    throw StabiliserModelFileError("field 'actuator_coupling' must have 2 values (c_xy, c_yx)");
  p.actuator_coupling = Eigen::Vector2d(coupling[0], coupling[1]);
  p.pan_detection_rate_rad_s = required<double>(s, "pan_detection_rate_rad_s");
  p.pan_detection_time_constant_s = required<double>(s, "pan_detection_time_constant_s");
  p.pan_release_corner_hz = required<double>(s, "pan_release_corner_hz");
  p.residual_time_constants_s =
      optional<std::vector<double>>(s, "residual_time_constants_s", {});
  const auto residual = optional<std::vector<double>>(s, "residual", {});
  const long k = static_cast<long>(p.residual_time_constants_s.size());
  if (static_cast<long>(residual.size()) != 4 * k)
    throw StabiliserModelFileError("field 'residual' must have 4 values per residual time constant");
  p.residual.resize(k > 0 ? 2 : 0, 2 * k);
  for (long r = 0; r < p.residual.rows(); ++r)
    for (long c = 0; c < p.residual.cols(); ++c)
      p.residual(r, c) = residual[static_cast<std::size_t>(r * 2 * k + c)];
  p.nonlinear_features = optional<std::string>(s, "nonlinear_features", "");
  const auto nonlinear = optional<std::vector<double>>(s, "nonlinear_residual", {});
  const long m = nonlinearFeatureCount(p.nonlinear_features);
  if (!p.nonlinear_features.empty() && m == 0)
    throw StabiliserModelFileError("field 'nonlinear_features': unknown set '" +
                                   p.nonlinear_features + "' (known: excursion_v1, rate_bank_v1, excursion_rate_v1)");
  if (static_cast<long>(nonlinear.size()) != 2 * m)
    throw StabiliserModelFileError("field 'nonlinear_residual' must have 2 x " +
                                   std::to_string(m) + " values for nonlinear_features '" +
                                   p.nonlinear_features + "'");
  p.nonlinear_residual.resize(m > 0 ? 2 : 0, m);
  for (long r = 0; r < p.nonlinear_residual.rows(); ++r)
    for (long c = 0; c < m; ++c)
      p.nonlinear_residual(r, c) = nonlinear[static_cast<std::size_t>(r * m + c)];
  if (s["learned_dynamics"]) {
    const YAML::Node learned = s["learned_dynamics"];
    try {
      p.learned_dynamics.network =
          std::make_shared<const LensDynamicsNetwork>(readLensDynamicsNetwork(learned["network"]));
    } catch (const LensDynamicsNetworkError& e) {
      throw StabiliserModelFileError(std::string("field 'learned_dynamics.network': ") + e.what());
    }
    const auto conditioning = required<std::vector<double>>(learned, "conditioning");
    p.learned_dynamics.conditioning =
        Eigen::Map<const Eigen::VectorXd>(conditioning.data(), static_cast<long>(conditioning.size()));
    const auto map = optional<std::vector<double>>(learned, "output_map", {1.0, 0.0, 0.0, 1.0});
    if (map.size() != 4)
      throw StabiliserModelFileError("field 'learned_dynamics.output_map' must have 4 values");
    p.learned_dynamics.output_map << map[0], map[1], map[2], map[3];
  }
  const std::string problem = p.validate();
  if (!problem.empty()) throw StabiliserModelFileError("stabiliser: " + problem);
  try {
    file.camera = readCameraDescription(root["camera"]);
  } catch (const std::invalid_argument& e) {
    throw StabiliserModelFileError(std::string("field ") + e.what());
  }
  if (root["training"]) {
    const YAML::Node t = root["training"];
    StabiliserTrainingRecord& record = file.training;
    record.target = optional<std::string>(t, "target", "");
    record.data_files = optional<std::vector<std::string>>(t, "data_files", {});
    record.data_sha256 = optional<std::string>(t, "data_sha256", "");
    record.recordings = optional<std::size_t>(t, "recordings", 0);
    record.observations = optional<std::size_t>(t, "observations", 0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    record.rms_without_model_px = optional<double>(t, "rms_without_model_px", nan);
    record.rms_px = optional<double>(t, "rms_px", nan);
    record.held_out_rms_without_model_px = optional<double>(t, "held_out_rms_without_model_px", nan);
    record.held_out_rms_px = optional<double>(t, "held_out_rms_px", nan);
    record.training_time_s = optional<double>(t, "training_time_s", 0.0);
  }
  return file;
}

StabiliserModelFile StabiliserModelFile::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw StabiliserModelFileError(path + ": cannot open the stabiliser model");
  std::stringstream text;
  text << in.rdbuf();
  try {
    return fromYaml(text.str());
  } catch (const StabiliserModelFileError& e) {
    throw StabiliserModelFileError(path + ": " + e.what());
  }
}

void StabiliserModelFile::checkSavable(const std::string& path) {
  const std::string partial = partialPathFor(path);
  {
    std::ofstream probe(partial);
    if (!probe) {
      const int error = errno;  // of the failed open, before anything else can change it
      throw StabiliserModelFileError(path + ": " + whyNotWritable(path, error));
    }
  }
  std::remove(partial.c_str());
}

void StabiliserModelFile::save(const std::string& path) const {
  // Written beside the target, then renamed over it: a reader (or a process killed mid-write)
  // sees the old complete file or the new complete file, never a partial one.
  const std::string partial = partialPathFor(path);
  {
    std::ofstream out(partial);
    if (!out) {
      const int error = errno;  // of the failed open, before anything else can change it
      throw StabiliserModelFileError(path + ": " + whyNotWritable(path, error));
    }
    out << "# deep_ois learned stabiliser model (core/ois/stabiliser_model.h): " << name << "\n"
        << toYaml();
    out.flush();
    if (!out) {
      const int error = errno;
      std::remove(partial.c_str());
      throw StabiliserModelFileError(path + ": write failed (" + std::strerror(error) + ")");
    }
  }
  if (std::rename(partial.c_str(), path.c_str()) != 0) {
    const int error = errno;
    std::remove(partial.c_str());
    throw StabiliserModelFileError(path + ": cannot replace it with the new model (rename failed: " +
                                   std::strerror(error) + ")");
  }
}

}  // namespace deep_ois
