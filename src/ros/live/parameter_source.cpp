#include "deep_ois/ros/live/parameter_source.h"

#include <stdexcept>

namespace deep_ois {

template <typename T>
bool NodeHandleParameters::read(const std::string& name, T& value, const char* expected) const {
  if (!nh_.hasParam(name)) return false;
  T read_value;
  if (!nh_.getParam(name, read_value)) {
    throw std::invalid_argument("parameter " + describe(name) + ": has the wrong type: expected " + expected);
  }
  value = read_value;
  return true;
}

template bool NodeHandleParameters::read(const std::string&, bool&, const char*) const;
template bool NodeHandleParameters::read(const std::string&, double&, const char*) const;
template bool NodeHandleParameters::read(const std::string&, int&, const char*) const;
template bool NodeHandleParameters::read(const std::string&, std::string&, const char*) const;
template bool NodeHandleParameters::read(const std::string&, std::vector<double>&, const char*) const;

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

template bool YamlParameters::read(const std::string&, bool&) const;
template bool YamlParameters::read(const std::string&, double&) const;
template bool YamlParameters::read(const std::string&, int&) const;
template bool YamlParameters::read(const std::string&, std::string&) const;
template bool YamlParameters::read(const std::string&, std::vector<double>&) const;

}  // namespace deep_ois
