// Where parameters come from: the ROS parameter server (nodelets) or a YAML file of the same
// shape (offline tools), so that both are read and validated by one loader.
#pragma once

#include <ros/node_handle.h>
#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

namespace deep_ois {

class ParameterSource {
 public:
  virtual ~ParameterSource() = default;
  // Each returns false (and leaves `value` alone) when the parameter is absent; throws
  // std::invalid_argument naming the parameter when it is present with the wrong type.
  virtual bool get(const std::string& name, bool& value) const = 0;
  virtual bool get(const std::string& name, double& value) const = 0;
  virtual bool get(const std::string& name, int& value) const = 0;
  virtual bool get(const std::string& name, std::string& value) const = 0;
  virtual bool get(const std::string& name, std::vector<double>& value) const = 0;
  // The parameter's full name for messages (e.g. /deep_ois/gyro_flow/readout_time).
  virtual std::string describe(const std::string& name) const = 0;

  // The value or `fallback` when absent.
  template <typename T>
  T param(const std::string& name, const T& fallback) const {
    T value = fallback;
    get(name, value);
    return value;
  }
};

// The parameter server under a node handle (a nodelet's private namespace). A parameter that is
// set with another type (a string where a number belongs, ...) is an error naming it, never a
// silent fall back to the default. Integers are accepted where a double belongs.
class NodeHandleParameters : public ParameterSource {
 public:
  explicit NodeHandleParameters(const ros::NodeHandle& nh) : nh_(nh) {}
  bool get(const std::string& name, bool& value) const override { return read(name, value, "true or false"); }
  bool get(const std::string& name, double& value) const override { return read(name, value, "a number"); }
  bool get(const std::string& name, int& value) const override { return read(name, value, "a whole number"); }
  bool get(const std::string& name, std::string& value) const override { return read(name, value, "a string"); }
  bool get(const std::string& name, std::vector<double>& value) const override {
    return read(name, value, "a list of numbers");
  }
  std::string describe(const std::string& name) const override { return nh_.resolveName(name); }

 private:
  template <typename T>
  bool read(const std::string& name, T& value, const char* expected) const;

  ros::NodeHandle nh_;
};

// A YAML mapping (e.g. config/gyro_flow.yaml) read as a private namespace.
class YamlParameters : public ParameterSource {
 public:
  // Throws std::runtime_error naming the file when it cannot be read or is not a mapping.
  explicit YamlParameters(const std::string& path);
  bool get(const std::string& name, bool& value) const override { return read(name, value); }
  bool get(const std::string& name, double& value) const override { return read(name, value); }
  bool get(const std::string& name, int& value) const override { return read(name, value); }
  bool get(const std::string& name, std::string& value) const override { return read(name, value); }
  bool get(const std::string& name, std::vector<double>& value) const override { return read(name, value); }
  std::string describe(const std::string& name) const override { return path_ + ": " + name; }

 private:
  template <typename T>
  bool read(const std::string& name, T& value) const;

  std::string path_;
  YAML::Node root_;
};

// Wraps a source and records every parameter a loader asks for, with the value the loader would
// use when it is absent (its default): the parameter tables in docs/ros_api.md are checked
// against what the loaders really read (test_parameter_docs), so the two cannot drift apart.
class RecordingParameters : public ParameterSource {
 public:
  struct Read {
    std::string name;
    std::string default_text;  // as YAML would write it: true, 0.5, centre, [1, 2]
  };
  explicit RecordingParameters(const ParameterSource& inner) : inner_(inner) {}
  bool get(const std::string& name, bool& value) const override {
    record(name, value ? "true" : "false");
    return inner_.get(name, value);
  }
  bool get(const std::string& name, double& value) const override;
  bool get(const std::string& name, int& value) const override {
    record(name, std::to_string(value));
    return inner_.get(name, value);
  }
  bool get(const std::string& name, std::string& value) const override {
    record(name, value);
    return inner_.get(name, value);
  }
  bool get(const std::string& name, std::vector<double>& value) const override;
  std::string describe(const std::string& name) const override { return inner_.describe(name); }

  // In the order first read; a name read twice is kept once.
  const std::vector<Read>& reads() const { return reads_; }

 private:
  void record(const std::string& name, const std::string& default_text) const;

  const ParameterSource& inner_;
  mutable std::vector<Read> reads_;
};

}  // namespace deep_ois
