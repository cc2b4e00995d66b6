#include "deep_ois/core/ois/lens_dynamics_network.h"

#include <unistd.h>

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

namespace deep_ois {
namespace {

constexpr const char* kFormatName = "deep_ois_lens_dynamics_network";
constexpr int kFormatVersion = 1;

std::vector<double> flatten(const Eigen::MatrixXd& m) {
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>(m.size()));
  for (long r = 0; r < m.rows(); ++r)
    for (long c = 0; c < m.cols(); ++c) values.push_back(m(r, c));
  return values;
}

template <typename T>
T required(const YAML::Node& node, const std::string& key) {
  if (!node[key]) throw LensDynamicsNetworkError("missing field '" + key + "'");
  try {
    return node[key].as<T>();
  } catch (const YAML::Exception&) {
    throw LensDynamicsNetworkError("field '" + key + "' is malformed");
  }
}

template <typename T>
T optional(const YAML::Node& node, const std::string& key, T fallback) {
  return node[key] ? required<T>(node, key) : fallback;
}

Eigen::MatrixXd matrixField(const YAML::Node& node, const std::string& key, long rows, long cols) {
  const auto values = required<std::vector<double>>(node, key);
  if (static_cast<long>(values.size()) != rows * cols)
    throw LensDynamicsNetworkError("field '" + key + "' must have " + std::to_string(rows) + " x " +
                                   std::to_string(cols) + " values (has " +
                                   std::to_string(values.size()) + ")");
  Eigen::MatrixXd m(rows, cols);
  for (long r = 0; r < rows; ++r)
    for (long c = 0; c < cols; ++c) m(r, c) = values[static_cast<std::size_t>(r * cols + c)];
  return m;
}

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

}  // namespace

std::string LensDynamicsNetwork::validate() const {
  std::ostringstream why;
  const long h = hidden_size, c = conditioning_size, gates = 3L * hidden_size;
  if (hidden_size <= 0) {
    why << "hidden_size: must be positive (got " << hidden_size << ")";
  } else if (conditioning_size < 0) {
    why << "conditioning_size: must be >= 0 (got " << conditioning_size << ")";
  } else if (!(step_s > 0.0 && step_s < 0.1)) {
    why << "step_s: must be in (0, 0.1) s (got " << step_s << ")";
  } else if (!(rate_scale_rad_s > 0.0) || !(output_scale > 0.0) || !std::isfinite(output_scale)) {
    why << "rate_scale_rad_s, output_scale: must be positive";
  } else if (w_input.rows() != gates || w_input.cols() != inputSize() + c || !w_input.allFinite()) {
    why << "w_input: must be a finite " << gates << " x " << inputSize() + c << " matrix";
  } else if (w_skip.size() != 0 && (w_skip.rows() != 2 || w_skip.cols() != inputSize() || !w_skip.allFinite())) {
    why << "w_skip: must be empty or a finite 2 x " << inputSize() << " matrix";
  } else if (w_hidden.rows() != gates || w_hidden.cols() != h || !w_hidden.allFinite()) {
    why << "w_hidden: must be a finite " << gates << " x " << h << " matrix";
  } else if (b_input.size() != gates || b_hidden.size() != gates || !b_input.allFinite() ||
             !b_hidden.allFinite()) {
    why << "b_input, b_hidden: must be " << gates << " finite values each";
  } else if (w_output.rows() != 2 || w_output.cols() != h || !w_output.allFinite() ||
             !b_output.allFinite()) {
    why << "w_output, b_output: must be a finite 2 x " << h << " matrix and 2 values";
  } else if (default_conditioning.size() != c || conditioning_spread.size() != c ||
             !default_conditioning.allFinite() || !(conditioning_spread.array() > 0.0).all()) {
    why << "default_conditioning, conditioning_spread: must be " << c
        << " finite values each, the spread positive";
  } else {
    for (double tau : input_integrals_s)
      if (!(tau > 0.0) || !std::isfinite(tau)) {
        why << "input_integrals_s: must be positive (got " << tau << ")";
        break;
      }
  }
  return why.str();
}

void writeLensDynamicsNetwork(YAML::Emitter& out, const LensDynamicsNetwork& net) {
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormatName;
  out << YAML::Key << "format_version" << YAML::Value << kFormatVersion;
  const LensDynamicsProvenance& p = net.provenance;
  out << YAML::Key << "provenance" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "generator" << YAML::Value << p.generator;
  out << YAML::Key << "design_seed_begin" << YAML::Value << p.design_seed_begin;
  out << YAML::Key << "design_seed_end" << YAML::Value << p.design_seed_end;
  out << YAML::Key << "designs" << YAML::Value << p.designs;
  out << YAML::Key << "motion_seeds_per_design" << YAML::Value << p.motion_seeds_per_design;
  out << YAML::Key << "trace_duration_s" << YAML::Value << p.trace_duration_s;
  out << YAML::Key << "focal_px" << YAML::Value << p.focal_px;
  out << YAML::Key << "iterations" << YAML::Value << p.iterations;
  out << YAML::Key << "training_loss" << YAML::Value << p.training_loss;
  out << YAML::Key << "validation_rms_focal" << YAML::Value << p.validation_rms_focal;
  out << YAML::Key << "command" << YAML::Value << p.command;
  out << YAML::EndMap;
  out << YAML::Key << "hidden_size" << YAML::Value << net.hidden_size;
  out << YAML::Key << "conditioning_size" << YAML::Value << net.conditioning_size;
  out << YAML::Key << "step_s" << YAML::Value << net.step_s;
  out << YAML::Key << "rate_scale_rad_s" << YAML::Value << net.rate_scale_rad_s;
  out << YAML::Key << "output_scale" << YAML::Value << net.output_scale;
  if (!net.input_integrals_s.empty())
    out << YAML::Key << "input_integrals_s" << YAML::Value << YAML::Flow << net.input_integrals_s;
  out << YAML::Key << "default_conditioning" << YAML::Value << YAML::Flow
      << flatten(net.default_conditioning);
  out << YAML::Key << "conditioning_spread" << YAML::Value << YAML::Flow
      << flatten(net.conditioning_spread);
  out << YAML::Key << "w_input" << YAML::Value << YAML::Flow << flatten(net.w_input);
  out << YAML::Key << "w_hidden" << YAML::Value << YAML::Flow << flatten(net.w_hidden);
  out << YAML::Key << "b_input" << YAML::Value << YAML::Flow << flatten(net.b_input);
  out << YAML::Key << "b_hidden" << YAML::Value << YAML::Flow << flatten(net.b_hidden);
  out << YAML::Key << "w_output" << YAML::Value << YAML::Flow << flatten(net.w_output);
  out << YAML::Key << "b_output" << YAML::Value << YAML::Flow << flatten(net.b_output);
  if (net.w_skip.size() != 0)
    out << YAML::Key << "w_skip" << YAML::Value << YAML::Flow << flatten(net.w_skip);
  out << YAML::EndMap;
}

std::string LensDynamicsNetwork::toYaml() const {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  writeLensDynamicsNetwork(out, *this);
  return std::string(out.c_str()) + "\n";
}

LensDynamicsNetwork LensDynamicsNetwork::fromYaml(const std::string& yaml_text) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw LensDynamicsNetworkError(std::string("not YAML: ") + e.what());
  }
  return readLensDynamicsNetwork(root);
}

LensDynamicsNetwork readLensDynamicsNetwork(const YAML::Node& root) {
  if (!root.IsMap() || optional<std::string>(root, "format", "") != kFormatName)
    throw LensDynamicsNetworkError(std::string("not a lens dynamics network (format: ") +
                                   kFormatName + " missing)");
  const int version = required<int>(root, "format_version");
  if (version != kFormatVersion)
    throw LensDynamicsNetworkError("format_version " + std::to_string(version) +
                                   " is not supported (this build reads " +
                                   std::to_string(kFormatVersion) + ")");
  LensDynamicsNetwork net;
  if (root["provenance"]) {
    const YAML::Node p = root["provenance"];
    LensDynamicsProvenance& record = net.provenance;
    record.generator = optional<std::string>(p, "generator", "");
    record.design_seed_begin = optional<std::uint32_t>(p, "design_seed_begin", 0);
    record.design_seed_end = optional<std::uint32_t>(p, "design_seed_end", 0);
    record.designs = optional<std::uint32_t>(p, "designs", 0);
    record.motion_seeds_per_design = optional<std::uint32_t>(p, "motion_seeds_per_design", 0);
    record.trace_duration_s = optional<double>(p, "trace_duration_s", 0.0);
    record.focal_px = optional<double>(p, "focal_px", 0.0);
    record.iterations = optional<std::uint64_t>(p, "iterations", 0);
    record.training_loss = optional<double>(p, "training_loss", 0.0);
    record.validation_rms_focal = optional<double>(p, "validation_rms_focal", 0.0);
    record.command = optional<std::string>(p, "command", "");
  }
  net.hidden_size = required<int>(root, "hidden_size");
  net.conditioning_size = required<int>(root, "conditioning_size");
  if (net.hidden_size <= 0 || net.hidden_size > 4096 || net.conditioning_size < 0 ||
      net.conditioning_size > 4096)
    throw LensDynamicsNetworkError("hidden_size, conditioning_size: out of range");
  net.step_s = required<double>(root, "step_s");
  net.rate_scale_rad_s = required<double>(root, "rate_scale_rad_s");
  net.output_scale = required<double>(root, "output_scale");
  net.input_integrals_s = optional<std::vector<double>>(root, "input_integrals_s", {});
  if (net.input_integrals_s.size() > 64)
    throw LensDynamicsNetworkError("input_integrals_s: at most 64 time constants");
  const long h = net.hidden_size, c = net.conditioning_size;
  net.default_conditioning = matrixField(root, "default_conditioning", c, 1);
  net.conditioning_spread = matrixField(root, "conditioning_spread", c, 1);
  net.w_input = matrixField(root, "w_input", 3 * h, net.inputSize() + c);
  net.w_hidden = matrixField(root, "w_hidden", 3 * h, h);
  net.b_input = matrixField(root, "b_input", 3 * h, 1);
  net.b_hidden = matrixField(root, "b_hidden", 3 * h, 1);
  net.w_output = matrixField(root, "w_output", 2, h);
  net.b_output = matrixField(root, "b_output", 2, 1);
  if (root["w_skip"]) net.w_skip = matrixField(root, "w_skip", 2, net.inputSize());
  const std::string problem = net.validate();
  if (!problem.empty()) throw LensDynamicsNetworkError(problem);
  return net;
}

LensDynamicsNetwork LensDynamicsNetwork::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw LensDynamicsNetworkError(path + ": cannot open the lens dynamics network");
  std::stringstream text;
  text << in.rdbuf();
  try {
    return fromYaml(text.str());
  } catch (const LensDynamicsNetworkError& e) {
    throw LensDynamicsNetworkError(path + ": " + e.what());
  }
}

std::shared_ptr<const LensDynamicsNetwork> loadLensDynamicsOption(const std::string& path_or_none) {
  if (path_or_none.empty() || path_or_none == "none") return nullptr;
  return std::make_shared<const LensDynamicsNetwork>(LensDynamicsNetwork::load(path_or_none));
}

void LensDynamicsNetwork::save(const std::string& path) const {
  // Written beside the target, then renamed over it: a reader (or a run killed mid-write) sees the
  // old complete file or the new one.
  const std::string partial = path + ".partial." + std::to_string(::getpid());
  {
    std::ofstream out(partial);
    if (!out)
      throw LensDynamicsNetworkError(path + ": cannot write (" + std::strerror(errno) + ")");
    out << "# deep_ois generic lens dynamics network (core/ois/lens_dynamics_network.h)\n"
        << toYaml();
    out.flush();
    if (!out) {
      std::remove(partial.c_str());
      throw LensDynamicsNetworkError(path + ": write failed");
    }
  }
  if (std::rename(partial.c_str(), path.c_str()) != 0) {
    const int error = errno;
    std::remove(partial.c_str());
    throw LensDynamicsNetworkError(path + ": rename failed (" + std::strerror(error) + ")");
  }
}

LensDynamicsRunner::LensDynamicsRunner(std::shared_ptr<const LensDynamicsNetwork> network,
                                       const Eigen::VectorXd& conditioning)
    : network_(std::move(network)) {
  if (!network_) throw std::invalid_argument("lens dynamics: no network");
  const std::string problem = network_->validate();
  if (!problem.empty()) throw std::invalid_argument("lens dynamics network: " + problem);
  if (conditioning.size() != network_->conditioning_size || !conditioning.allFinite())
    throw std::invalid_argument("lens dynamics: the conditioning vector must have " +
                                std::to_string(network_->conditioning_size) + " finite values");
  const long c = network_->conditioning_size;
  conditioned_bias_ = network_->b_input;
  if (c > 0)
    conditioned_bias_ += network_->w_input.rightCols(c) * conditioning;
  for (double tau : network_->input_integrals_s) {
    const double decay = std::exp(-network_->step_s / tau);
    integral_decay_.push_back(decay);
    integral_weight_.push_back(tau * (1.0 - decay));
  }
  gates_input_.resize(3L * network_->hidden_size);
  gates_hidden_.resize(3L * network_->hidden_size);
  reset();
}

void LensDynamicsRunner::reset() {
  hidden_ = Eigen::VectorXd::Zero(network_->hidden_size);
  integrals_ = Eigen::VectorXd::Zero(2L * static_cast<long>(integral_decay_.size()));
  inputs_ = Eigen::VectorXd::Zero(network_->inputSize());
}

Eigen::Vector2d LensDynamicsRunner::step(const Eigen::Vector3d& rate_rad_s) {
  const LensDynamicsNetwork& net = *network_;
  const long h = net.hidden_size;
  const long k_count = static_cast<long>(integral_decay_.size());
  inputs_.head<3>() = rate_rad_s / net.rate_scale_rad_s;
  for (long k = 0; k < k_count; ++k) {
    for (int axis = 0; axis < 2; ++axis) {
      double& integral = integrals_(axis * k_count + k);
      integral = integral_decay_[k] * integral + integral_weight_[k] * rate_rad_s(axis);
      inputs_(3 + axis * k_count + k) = integral / net.output_scale;
    }
  }
  gates_input_.noalias() = net.w_input.leftCols(net.inputSize()) * inputs_ + conditioned_bias_;
  gates_hidden_.noalias() = net.w_hidden * hidden_ + net.b_hidden;
  for (long i = 0; i < h; ++i) {
    const double r = sigmoid(gates_input_(i) + gates_hidden_(i));
    const double z = sigmoid(gates_input_(h + i) + gates_hidden_(h + i));
    const double n = std::tanh(gates_input_(2 * h + i) + r * gates_hidden_(2 * h + i));
    hidden_(i) = (1.0 - z) * n + z * hidden_(i);
  }
  Eigen::Vector2d output = net.w_output * hidden_ + net.b_output;
  if (net.w_skip.size() != 0) output += net.w_skip * inputs_;
  return net.output_scale * output;
}

}  // namespace deep_ois
