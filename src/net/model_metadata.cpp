#include "deep_ois/net/model_metadata.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/camera/camera_description_yaml.h"

namespace deep_ois {

namespace {

template <typename T>
T required(const YAML::Node& node, const std::string& key, const std::string& path) {
  const YAML::Node value = node[key];
  if (!value) throw std::runtime_error("model metadata: missing field '" + path + key + "'");
  try {
    return value.as<T>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error("model metadata: field '" + path + key + "' has the wrong type");
  }
}

template <typename T>
T optional(const YAML::Node& node, const std::string& key, const std::string& path, const T& fallback) {
  const YAML::Node value = node[key];
  if (!value) return fallback;
  try {
    return value.as<T>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error("model metadata: field '" + path + key + "' has the wrong type");
  }
}

void emitSequence(YAML::Emitter& out, const std::string& key, const std::vector<double>& values) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << values;
}

}  // namespace

std::string ModelMetadata::validate() const {
  if (format_version != kFormatVersion) {
    return "format_version " + std::to_string(format_version) + " is not the supported " +
           std::to_string(kFormatVersion);
  }
  if (architecture.widths.size() < 2) return "architecture.widths needs at least two levels";
  for (int width : architecture.widths) {
    if (width < 1 || width > 4096) return "architecture.widths holds " + std::to_string(width);
  }
  if (architecture.normalization != "instance" && architecture.normalization != "none") {
    return "architecture.normalization is '" + architecture.normalization + "', not instance|none";
  }
  const int pools = static_cast<int>(architecture.widths.size()) - 1;
  const int smallest = std::min(working_grid.width, working_grid.height);
  if (working_grid.width < 1 || working_grid.height < 1 || (smallest >> pools) < 1) {
    return "working_grid " + std::to_string(working_grid.width) + "x" + std::to_string(working_grid.height) +
           " is too small for " + std::to_string(pools) + " pooling steps";
  }
  for (int c = 0; c < 2; ++c) {
    if (!std::isfinite(input_mean_px[c])) return "input_mean_px is not finite";
    if (!(input_std_px[c] > 0.0) || !std::isfinite(input_std_px[c])) return "input_std_px must be positive";
  }
  for (double tau : history_time_constants_s) {
    if (!(tau > 0.0) || !std::isfinite(tau)) return "history_time_constants_s must be positive seconds";
  }
  const std::size_t history_channels = 2 * history_time_constants_s.size();
  if (history_mean_px.size() != history_channels || history_std_px.size() != history_channels) {
    return "history_mean_px and history_std_px need 2 values per history time constant (" +
           std::to_string(history_channels) + ")";
  }
  for (std::size_t c = 0; c < history_channels; ++c) {
    if (!std::isfinite(history_mean_px[c])) return "history_mean_px is not finite";
    if (!(history_std_px[c] > 0.0) || !std::isfinite(history_std_px[c])) return "history_std_px must be positive";
  }
  return "";
}

void ModelMetadata::setHistoryTimeConstants(const std::vector<double>& time_constants_s) {
  history_time_constants_s = time_constants_s;
  history_mean_px.assign(2 * time_constants_s.size(), 0.0);
  history_std_px.assign(2 * time_constants_s.size(), 1.0);
}

std::string ModelMetadata::toYaml() const {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format_version" << YAML::Value << format_version;
  out << YAML::Key << "preset" << YAML::Value << preset;
  out << YAML::Key << "architecture" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "widths" << YAML::Value << YAML::Flow << architecture.widths;
  out << YAML::Key << "normalization" << YAML::Value << architecture.normalization;
  out << YAML::Key << "residual" << YAML::Value << architecture.residual;
  out << YAML::EndMap;
  out << YAML::Key << "working_grid" << YAML::Value << YAML::Flow << YAML::BeginSeq << working_grid.width
      << working_grid.height << YAML::EndSeq << YAML::Comment("width, height");
  out << YAML::Key << "input_mean_px" << YAML::Value << YAML::Flow
      << std::vector<double>{input_mean_px[0], input_mean_px[1]};
  out << YAML::Key << "input_std_px" << YAML::Value << YAML::Flow
      << std::vector<double>{input_std_px[0], input_std_px[1]};
  emitSequence(out, "history_time_constants_s", history_time_constants_s);
  emitSequence(out, "history_mean_px", history_mean_px);
  emitSequence(out, "history_std_px", history_std_px);
  writeCameraDescription(out, camera);
  out << YAML::Key << "training" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "data_files" << YAML::Value << training.data_files;
  out << YAML::Key << "data_sha256" << YAML::Value << training.data_sha256;
  if (!training.legacy_data_fnv1a64.empty()) {
    out << YAML::Key << "data_hash" << YAML::Value << training.legacy_data_fnv1a64
        << YAML::Comment("FNV-1a 64, from before data_sha256");
  }
  out << YAML::Key << "train_pairs" << YAML::Value << training.train_pairs;
  out << YAML::Key << "validation_pairs" << YAML::Value << training.validation_pairs;
  out << YAML::Key << "epochs" << YAML::Value << training.epochs;
  out << YAML::Key << "batch_size" << YAML::Value << training.batch_size;
  out << YAML::Key << "learning_rate" << YAML::Value << training.learning_rate;
  out << YAML::Key << "loss" << YAML::Value << training.loss;
  out << YAML::Key << "seed" << YAML::Value << training.seed;
  emitSequence(out, "train_loss", training.train_loss);
  emitSequence(out, "validation_loss", training.validation_loss);
  emitSequence(out, "validation_epe_px", training.validation_epe_px);
  emitSequence(out, "validation_gyro_epe_px", training.validation_gyro_epe_px);
  out << YAML::Key << "training_time_s" << YAML::Value << training.training_time_s;
  out << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

ModelMetadata ModelMetadata::fromYaml(const std::string& yaml_text) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(std::string("model metadata is not YAML: ") + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error("model metadata is not a YAML map");
  ModelMetadata m;
  m.format_version = required<int>(root, "format_version", "");
  if (m.format_version != kFormatVersion) {
    throw std::runtime_error("model metadata: format_version " + std::to_string(m.format_version) +
                             " is not the supported " + std::to_string(kFormatVersion));
  }
  m.preset = required<std::string>(root, "preset", "");
  const YAML::Node architecture = root["architecture"];
  if (!architecture || !architecture.IsMap()) throw std::runtime_error("model metadata: missing map 'architecture'");
  m.architecture.widths = required<std::vector<int>>(architecture, "widths", "architecture.");
  m.architecture.normalization = required<std::string>(architecture, "normalization", "architecture.");
  m.architecture.residual = required<bool>(architecture, "residual", "architecture.");
  const auto grid = required<std::vector<int>>(root, "working_grid", "");
  if (grid.size() != 2) throw std::runtime_error("model metadata: working_grid needs [width, height]");
  m.working_grid = cv::Size(grid[0], grid[1]);
  const auto mean = required<std::vector<double>>(root, "input_mean_px", "");
  const auto std_px = required<std::vector<double>>(root, "input_std_px", "");
  if (mean.size() != 2 || std_px.size() != 2) {
    throw std::runtime_error("model metadata: input_mean_px and input_std_px need [u, v]");
  }
  m.input_mean_px = {mean[0], mean[1]};
  m.input_std_px = {std_px[0], std_px[1]};
  // Absent in models from before the motion history: the gyro flow alone.
  m.history_time_constants_s = optional<std::vector<double>>(root, "history_time_constants_s", "", {});
  m.history_mean_px = optional<std::vector<double>>(root, "history_mean_px", "", {});
  m.history_std_px = optional<std::vector<double>>(root, "history_std_px", "", {});
  try {
    m.camera = readCameraDescription(root["camera"]);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("model metadata: field ") + e.what());
  }
  const YAML::Node training = root["training"];
  if (training && training.IsMap()) {
    TrainingRecord& t = m.training;
    t.data_files = optional<std::vector<std::string>>(training, "data_files", "training.", {});
    t.data_sha256 = optional<std::string>(training, "data_sha256", "training.", "");
    t.legacy_data_fnv1a64 = optional<std::string>(training, "data_hash", "training.", "");
    t.train_pairs = optional<std::size_t>(training, "train_pairs", "training.", 0);
    t.validation_pairs = optional<std::size_t>(training, "validation_pairs", "training.", 0);
    t.epochs = optional<int>(training, "epochs", "training.", 0);
    t.batch_size = optional<int>(training, "batch_size", "training.", 0);
    t.learning_rate = optional<double>(training, "learning_rate", "training.", 0.0);
    t.loss = optional<std::string>(training, "loss", "training.", "");
    t.seed = optional<unsigned>(training, "seed", "training.", 0);
    t.train_loss = optional<std::vector<double>>(training, "train_loss", "training.", {});
    t.validation_loss = optional<std::vector<double>>(training, "validation_loss", "training.", {});
    t.validation_epe_px = optional<std::vector<double>>(training, "validation_epe_px", "training.", {});
    t.validation_gyro_epe_px = optional<std::vector<double>>(training, "validation_gyro_epe_px", "training.", {});
    t.training_time_s = optional<double>(training, "training_time_s", "training.", 0.0);
  }
  const std::string problem = m.validate();
  if (!problem.empty()) throw std::runtime_error("model metadata: " + problem);
  return m;
}

ModelMetadata presetMetadata(const std::string& preset) {
  ModelMetadata m;
  m.preset = preset;
  if (preset == "paper") {
    // The authors' network: 5 levels, widths 32-64-128-256 and 256 at the bottleneck, instance
    // normalisation, the compensated flow predicted directly, at the full 360x270 grid.
    m.architecture.widths = {32, 64, 128, 256, 256};
    m.architecture.normalization = "instance";
    m.architecture.residual = false;
    m.working_grid = cv::Size(360, 270);
  } else if (preset == "fast") {
    // The flow is smooth (six homographies per frame), so a 1/6-resolution grid upsampled at the
    // end loses little; 4 levels of 8-16-32-32 run in about 5 ms on one core (16-32-64-64 at
    // 90x68 took 15-20 ms: torch's small convolutions are overhead-bound).
    m.architecture.widths = {8, 16, 32, 32};
    m.architecture.normalization = "none";
    m.architecture.residual = true;
    m.working_grid = cv::Size(60, 45);
    m.setHistoryTimeConstants(kDefaultHistoryTimeConstantsS);
  } else {
    throw std::runtime_error("unknown model preset '" + preset + "' (expected fast or paper)");
  }
  return m;
}

}  // namespace deep_ois
