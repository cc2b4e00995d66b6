// Reading the stages' fields of a stabiliser model file (core/ois/stabiliser_stage.h): a missing or
// malformed field throws StabiliserModelFileError naming it, as the rest of the file's reader does.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model_file.h"

namespace deep_ois {
namespace stabiliser_file_fields {

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

// A 2 x 2 matrix as the file writes it: row by row, in one flow list.
inline std::vector<double> rowMajor(const Eigen::Matrix2d& m) {
  return {m(0, 0), m(0, 1), m(1, 0), m(1, 1)};
}

// A stage's values as one map under its key: numbers (written in full, 17 digits: a designed
// stabiliser's values are its definition, not a fit's estimate), words and flags by name, all
// written, all required when the map is there.
struct ValueFields {
  std::vector<std::pair<const char*, double*>> numbers;
  std::vector<std::pair<const char*, std::string*>> words;
  std::vector<std::pair<const char*, bool*>> flags;
};

inline void writeValueMap(YAML::Emitter& out, const char* key, const ValueFields& fields) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  for (const auto& [name, value] : fields.words) out << YAML::Key << name << YAML::Value << *value;
  for (const auto& [name, value] : fields.flags) out << YAML::Key << name << YAML::Value << *value;
  for (const auto& [name, value] : fields.numbers)
    out << YAML::Key << name << YAML::Value << YAML::DoublePrecision(17) << *value;
  out << YAML::EndMap;
}

// False when the section has no such map (the stage is not in the model).
inline bool readValueMap(const YAML::Node& section, const std::string& key, const ValueFields& fields) {
  const YAML::Node map = section[key];
  if (!map) return false;
  if (!map.IsMap()) throw StabiliserModelFileError("field '" + key + "' must be a map");
  try {
    for (const auto& [name, value] : fields.words) *value = required<std::string>(map, name);
    for (const auto& [name, value] : fields.flags) *value = required<bool>(map, name);
    for (const auto& [name, value] : fields.numbers) *value = required<double>(map, name);
  } catch (const StabiliserModelFileError& e) {
    throw StabiliserModelFileError(key + ": " + e.what());
  }
  return true;
}

}  // namespace stabiliser_file_fields
}  // namespace deep_ois
