// dynamic_reconfigure server of the compensation nodelet's live-tunable parameters
// (cfg/Compensation.cfg): color_max_flow, warp_iterations, warp_threads, max_wait, learning,
// learning_cpu_share.
#pragma once

#include <deep_ois/CompensationConfig.h>
#include <dynamic_reconfigure/server.h>
#include <ros/node_handle.h>

#include <boost/thread/recursive_mutex.hpp>
#include <functional>
#include <string>

namespace deep_ois {

// The live-tunable subset of the compensation parameters (units as in CompensationParameters).
struct CompensationLiveParameters {
  double color_max_flow_px = 0.0;  // flow magnitude at full brightness; 0 = per-frame maximum
  int warp_iterations = 3;         // fixed-point steps inverting the flow, 0-20
  int warp_threads = 1;            // OpenCV threads of the warp (cv::setNumThreads, process-wide), >= 1
  double max_wait_s = 1.0;         // wall time a gyro flow waits for its frames
  bool learning = true;            // online learning of the stabiliser model on or off
  double learning_cpu_share = 0.3; // its average CPU, share of one core, (0, 1]
  bool fusion = false;             // a stabiliser model's motion refined by the tracks (docs/fusion.md)
};

// Empty when `config` is valid (and copied into `params`); otherwise a sentence naming the bad
// parameter, and `params` is unchanged.
std::string applyCompensationConfig(const CompensationConfig& config, CompensationLiveParameters& params);

// Serves ~set_parameters on the private node handle, starting from the loaded values, and hands
// every valid change to `apply` (the wrapper copies it into its parameters under its lock; the
// motion history and the cached frames stay). Same threading as GyroFlowReconfigure: `apply`
// runs once inside the constructor and then on the private handle's queue.
class CompensationReconfigure {
 public:
  using Apply = std::function<void(const CompensationLiveParameters&)>;
  CompensationReconfigure(const ros::NodeHandle& private_nh, const std::string& log_name,
                          const CompensationLiveParameters& loaded, Apply apply);

 private:
  void callback(CompensationConfig& config, uint32_t level);

  std::string log_name_;
  CompensationLiveParameters current_;
  Apply apply_;
  boost::recursive_mutex server_mutex_;
  dynamic_reconfigure::Server<CompensationConfig> server_;
};

}  // namespace deep_ois
