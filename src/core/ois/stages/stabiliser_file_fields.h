// Reading the stages' fields of a stabiliser model file (core/ois/stabiliser_stage.h): a missing or
// malformed field throws StabiliserModelFileError naming it, as the rest of the file's reader does.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
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

}  // namespace stabiliser_file_fields
}  // namespace deep_ois
