#include "deep_ois/ros/live/parameter_source.h"

#include <stdexcept>

namespace deep_ois {

YamlParameters::YamlParameters(const std::string& path) : path_(path) {
  try {
    root_ = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": cannot read the parameter file: " + e.what());
  }
  if (!root_.IsMap()) throw std::runtime_error(path + ": a parameter file must be a YAML mapping");
}

template <typename T>
bool YamlParameters::read(const std::string& name, T& value) const {
  const YAML::Node node = root_[name];
  if (!node) return false;
  try {
    value = node.as<T>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument("parameter " + describe(name) + ": has the wrong type");
  }
  return true;
}

template bool YamlParameters::read(const std::string&, double&) const;
template bool YamlParameters::read(const std::string&, int&) const;
template bool YamlParameters::read(const std::string&, std::string&) const;
template bool YamlParameters::read(const std::string&, std::vector<double>&) const;

}  // namespace deep_ois
