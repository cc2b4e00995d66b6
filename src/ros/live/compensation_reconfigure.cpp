#include "deep_ois/ros/live/compensation_reconfigure.h"

#include <ros/console.h>

#include <cmath>

namespace deep_ois {

namespace {
CompensationConfig toConfig(const CompensationLiveParameters& params) {
  CompensationConfig config = CompensationConfig::__getDefault__();
  config.color_max_flow = params.color_max_flow_px;
  config.warp_iterations = params.warp_iterations;
  config.warp_threads = params.warp_threads;
  config.max_wait = params.max_wait_s;
  config.learning = params.learning;
  config.learning_cpu_share = params.learning_cpu_share;
  config.fusion = params.fusion;
  return config;
}
}  // namespace

std::string applyCompensationConfig(const CompensationConfig& config, CompensationLiveParameters& params) {
  // The same bounds as loadCompensationParameters.
  if (!std::isfinite(config.color_max_flow) || config.color_max_flow < 0.0) {
    return "color_max_flow must be >= 0 pixels, got " + std::to_string(config.color_max_flow);
  }
  if (config.warp_iterations < 0 || config.warp_iterations > 20) {
    return "warp_iterations must be in [0, 20], got " + std::to_string(config.warp_iterations);
  }
  if (config.warp_threads < 1) return "warp_threads must be at least 1, got " + std::to_string(config.warp_threads);
  if (!std::isfinite(config.max_wait) || config.max_wait < 0.0) {
    return "max_wait must be >= 0 seconds, got " + std::to_string(config.max_wait);
  }
  if (!(config.learning_cpu_share > 0.0 && config.learning_cpu_share <= 1.0)) {
    return "learning_cpu_share must be in (0, 1], got " + std::to_string(config.learning_cpu_share);
  }
  params.learning = config.learning;
  params.learning_cpu_share = config.learning_cpu_share;
  params.fusion = config.fusion;
  params.color_max_flow_px = config.color_max_flow;
  params.warp_iterations = config.warp_iterations;
  params.warp_threads = config.warp_threads;
  params.max_wait_s = config.max_wait;
  return "";
}

CompensationReconfigure::CompensationReconfigure(const ros::NodeHandle& private_nh, const std::string& log_name,
                                                 const CompensationLiveParameters& loaded, Apply apply)
    : log_name_(log_name), current_(loaded), apply_(std::move(apply)), server_(server_mutex_, private_nh) {
  CompensationConfig initial = toConfig(loaded);
  server_.updateConfig(initial);
  server_.setCallback([this](CompensationConfig& config, uint32_t level) { callback(config, level); });
}

void CompensationReconfigure::callback(CompensationConfig& config, uint32_t) {
  CompensationLiveParameters updated = current_;
  const std::string problem = applyCompensationConfig(config, updated);
  if (!problem.empty()) {
    ROS_WARN_NAMED(log_name_, "%s: reconfigure refused: %s; keeping the previous values",
                   log_name_.c_str(), problem.c_str());
    config = toConfig(current_);
    return;
  }
  const bool changed = updated.color_max_flow_px != current_.color_max_flow_px ||
                       updated.warp_iterations != current_.warp_iterations ||
                       updated.warp_threads != current_.warp_threads ||
                       updated.max_wait_s != current_.max_wait_s || updated.learning != current_.learning ||
                       updated.learning_cpu_share != current_.learning_cpu_share || updated.fusion != current_.fusion;
  current_ = updated;
  if (changed) {
    ROS_INFO_NAMED(log_name_,
                   "%s: reconfigured: color max flow %.2f px, %d warp iterations, %d warp thread(s), max wait %.3f s, "
                   "learning %s (%.0f %% of a core), fusion %s",
                   log_name_.c_str(), config.color_max_flow, config.warp_iterations, config.warp_threads,
                   config.max_wait, config.learning ? "on" : "off", 100.0 * config.learning_cpu_share,
                   config.fusion ? "on" : "off");
  }
  apply_(current_);
}

}  // namespace deep_ois
