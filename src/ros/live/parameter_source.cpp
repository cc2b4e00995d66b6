#include "deep_ois/ros/live/parameter_source.h"

#include <sstream>
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

namespace {
std::string shortest(double x) {
  std::ostringstream out;
  out.precision(15);
  out << x;
  return out.str();
}
}  // namespace

bool RecordingParameters::get(const std::string& name, double& value) const {
  record(name, shortest(value));
  return inner_.get(name, value);
}

bool RecordingParameters::get(const std::string& name, std::vector<double>& value) const {
  std::string text = "[";
  for (std::size_t k = 0; k < value.size(); ++k) text += (k ? ", " : "") + shortest(value[k]);
  record(name, text + "]");
  return inner_.get(name, value);
}

void RecordingParameters::record(const std::string& name, const std::string& default_text) const {
  for (const Read& read : reads_) {
    if (read.name == name) return;
  }
  reads_.push_back({name, default_text});
}

}  // namespace deep_ois
