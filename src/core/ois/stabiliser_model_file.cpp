#include "deep_ois/core/ois/stabiliser_model_file.h"

#include <algorithm>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/camera/camera_description_yaml.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "stages/stabiliser_file_fields.h"

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

// The same field readers as the stages' (their errors name the field).
using stabiliser_file_fields::optional;
using stabiliser_file_fields::required;

// A stage older files may have that this build no longer has, and that no stage of it can stand
// in for: such a file is refused by name, never loaded without it (it would predict otherwise).
struct RetiredStage {
  const char* name;  // as a `stages` list named it
  const char* key;   // its key in the `stabiliser` section
  const char* what;  // in words, and why it went
};
constexpr RetiredStage kRetiredStages[] = {
    {"learned_lens_dynamics", "learned_dynamics",
     "the recurrent lens network pretrained on generated designs, removed because the "
     "linear-dynamics stage explains more of the lens motion on held-out designs"},
};

// Throws StabiliserModelFileError naming the first retired stage the section has.
void refuseRetiredStages(const YAML::Node& section) {
  const auto named = section["stages"] ? optional<std::vector<std::string>>(section, "stages", {})
                                       : std::vector<std::string>();
  for (const RetiredStage& retired : kRetiredStages) {
    if (!section[retired.key] && std::find(named.begin(), named.end(), retired.name) == named.end())
      continue;
    throw StabiliserModelFileError(
        std::string("stabiliser: stage '") + retired.name + "' (field '" + retired.key + "': " +
        retired.what + ") is no longer supported and has no successor to convert it to; retrain "
        "the camera's model with train_stabiliser");
  }
}

// The residual stages of older files, removed because the chain without them explained the lens
// motion of held-out designs as well (benchmark_lens_dynamics --residuals false, 2026-12): both
// added to the lens, after the chain, a linear map of leaky integrals of the pan/tilt rate,
// y_k' = rate - y_k / tau_k. The linear bank (`residual_time_constants_s`, `residual`: 2 x 2K, the
// K x integrals then the K y integrals) and the learned rate bank (`nonlinear_features:
// rate_bank_v1`, `nonlinear_residual`: 2 x 18 over these nine time constants) convert exactly to a
// linear-dynamics stage with output `lens` over first-order low-passes of those time constants.
// The learned sets of nonlinear features (excursion_v1, excursion_rate_v1) have no successor.
constexpr double kRateBankTimeConstantsS[] = {0.002, 0.005, 0.012, 0.03, 0.07, 0.17, 0.4, 1.0, 2.5};

// Whether an older stage's keys act: the file names no stage list, or its list names the stage.
bool listedOrDefault(const YAML::Node& section, const char* stage) {
  if (!section["stages"]) return true;
  const auto named = optional<std::vector<std::string>>(section, "stages", {});
  return std::find(named.begin(), named.end(), stage) != named.end();
}

// Appends a 2 x 2K bank (the K x columns, then the K y columns, row-major in `values`) at the time
// constants `taus` to the converted stage's time constants and coefficient columns.
void appendBank(const std::vector<double>& taus, const std::vector<double>& values, const std::string& field,
                std::vector<double>* all_taus, std::vector<Eigen::Vector2d>* x_columns,
                std::vector<Eigen::Vector2d>* y_columns) {
  const std::size_t k = taus.size();
  if (values.size() != 4 * k)
    throw StabiliserModelFileError("field '" + field + "' must have 2 x " + std::to_string(2 * k) + " values");
  for (std::size_t j = 0; j < k; ++j) {
    all_taus->push_back(taus[j]);
    x_columns->emplace_back(values[j], values[2 * k + j]);
    y_columns->emplace_back(values[k + j], values[2 * k + k + j]);
  }
}

// The residual stages of an older `stabiliser` section as the linear-dynamics stage that predicts
// the same lens (nothing when the section has none). Throws StabiliserModelFileError for a set of
// nonlinear features (no successor) and for a file that has a linear-dynamics stage as well (one
// stage cannot hold both).
std::optional<LinearDynamicsValues> convertedResidualStages(const YAML::Node& section) {
  std::vector<double> taus;
  std::vector<Eigen::Vector2d> x_columns, y_columns;
  if (listedOrDefault(section, "linear_residual")) {
    appendBank(optional<std::vector<double>>(section, "residual_time_constants_s", {}),
               optional<std::vector<double>>(section, "residual", {}), "residual", &taus, &x_columns, &y_columns);
  }
  const std::string features = optional<std::string>(section, "nonlinear_features", "");
  if (!features.empty() && listedOrDefault(section, "learned_residual")) {
    if (features == "excursion_v1" || features == "excursion_rate_v1")
      throw StabiliserModelFileError(
          "stabiliser: stage 'learned_residual' with nonlinear_features '" + features +
          "' (nonlinear functions of the chain's state, removed because the chain without them "
          "explains the lens motion of held-out designs as well) is no longer supported and has no "
          "successor to convert it to; retrain the camera's model with train_stabiliser");
    if (features != "rate_bank_v1")
      throw StabiliserModelFileError("field 'nonlinear_features': unknown set '" + features + "'");
    appendBank(std::vector<double>(std::begin(kRateBankTimeConstantsS), std::end(kRateBankTimeConstantsS)),
               optional<std::vector<double>>(section, "nonlinear_residual", {}), "nonlinear_residual", &taus,
               &x_columns, &y_columns);
  }
  if (taus.empty()) return std::nullopt;
  if (section["linear_dynamics"])
    throw StabiliserModelFileError(
        "stabiliser: the file has a linear_dynamics stage and a residual bank (residual or "
        "nonlinear_residual), which one linear_dynamics stage cannot both hold; retrain the "
        "camera's model with train_stabiliser");
  LinearDynamicsValues converted;
  converted.output_to_lens = true;
  converted.basis.time_constants_s = taus;
  converted.basis.order = static_cast<int>(taus.size());
  // Columns axis-major as the basis' state: the x integrals, the y integrals, the z ones (0: the
  // banks read the pan/tilt rate only).
  const long k = converted.basis.order;
  converted.coefficients = Eigen::MatrixXd::Zero(2, 3 * k);
  for (long j = 0; j < k; ++j) {
    converted.coefficients.col(j) = x_columns[static_cast<std::size_t>(j)];
    converted.coefficients.col(k + j) = y_columns[static_cast<std::size_t>(j)];
  }
  return converted;
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
  // Each stage writes its own keys (core/ois/stabiliser_stage.h): those of the first format in the
  // order files have always had them (so a model rewritten is the same bytes), then any later
  // stage in the chain's order.
  out << YAML::Key << "stabiliser" << YAML::Value << YAML::BeginMap;
  static const char* const kFirstFormatOrder[] = {
      "centring", "actuator", "stroke", "excursion_centring", "actuator_coupling", "pan_detection"};
  // A stage the model has not got writes nothing, except the default chain's, whose keys the
  // first format required: those write their defaults (a model of other stages, a generated
  // design, still loads in a reader of that format).
  auto write = [&](const StabiliserStage& stage) {
    if (const StageValues* own = parameters.values(stage.name))
      stage.write(out, *own);
    else if (stage.in_default_chain)
      stage.write(out, *stage.make());
  };
  for (const char* name : kFirstFormatOrder) write(stabiliserStage(name));
  for (const StabiliserStage& stage : stabiliserStages()) {
    if (std::find_if(std::begin(kFirstFormatOrder), std::end(kFirstFormatOrder),
                     [&](const char* name) { return name == std::string(stage.name); }) ==
        std::end(kFirstFormatOrder))
      write(stage);
  }
  // A model that is not the default chain names its stages (optional: older files have none).
  if (!parameters.hasDefaultChain())
    out << YAML::Key << "stages" << YAML::Value << YAML::Flow << parameters.stageNames();
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
  refuseRetiredStages(s);
  const std::optional<LinearDynamicsValues> converted = convertedResidualStages(s);
  // Every stage the section has; a file that names its stages keeps only those (without the
  // list: the default chain and any sampled controller's stage the file has).
  StabiliserModel& p = file.parameters;
  p = StabiliserModel(std::vector<std::string>{});
  for (const StabiliserStage& stage : stabiliserStages()) {
    std::unique_ptr<StageValues> own = stage.make();
    if (stage.read(s, *own)) p.put(stage.name, std::move(own));
  }
  if (s["stages"]) {
    const auto named = optional<std::vector<std::string>>(s, "stages", {});
    for (const std::string& name : named) {
      if (name == "linear_residual" || name == "learned_residual") continue;  // converted above
      try {
        stabiliserStage(name);
      } catch (const std::invalid_argument& e) {
        throw StabiliserModelFileError(std::string("stabiliser: stages: ") + e.what());
      }
    }
    for (const std::string& name : p.stageNames())
      if (std::find(named.begin(), named.end(), name) == named.end()) p.remove(name);
  }
  if (converted) p.set(*converted);
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
