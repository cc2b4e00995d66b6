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
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/camera/camera_description_yaml.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
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
      "centring",          "actuator",        "stroke",           "excursion_centring",
      "actuator_coupling", "pan_detection",   "linear_residual",  "learned_residual"};
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
      try {
        stabiliserStage(name);
      } catch (const std::invalid_argument& e) {
        throw StabiliserModelFileError(std::string("stabiliser: stages: ") + e.what());
      }
    }
    for (const std::string& name : p.stageNames())
      if (std::find(named.begin(), named.end(), name) == named.end()) p.remove(name);
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
