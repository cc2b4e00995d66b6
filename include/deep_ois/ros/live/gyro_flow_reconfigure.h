// dynamic_reconfigure server of the gyro flow nodelet's live-tunable parameters (cfg/GyroFlow.cfg):
// time_offset, readout_time, patch_time, color_max_flow, imu_wait_timeout, gyro_bias_x/y/z,
// r_cam_imu (the mount, ~imu_to_camera_rotation as text).
#pragma once

#include <deep_ois/GyroFlowConfig.h>
#include <deep_ois/OnlineCalibration.h>
#include <dynamic_reconfigure/server.h>
#include <ros/node_handle.h>

#include <boost/thread/recursive_mutex.hpp>
#include <functional>
#include <string>

#include "deep_ois/ros/live/gyro_flow_parameters.h"

namespace deep_ois {

// Copies the live-tunable values of `config` into `params`. Empty when they are valid; otherwise
// a sentence naming the bad parameter, and `params` is left unchanged.
std::string applyGyroFlowConfig(const GyroFlowConfig& config, GyroFlowParameters& params);
// The live-tunable values of `params` as a reconfigure config.
GyroFlowConfig toGyroFlowConfig(const GyroFlowParameters& params);
// The online calibration's values in `params`: time offset, readout, gyro bias and, when the mount
// is estimated (~online_calibration_mount), R_cam_imu from the message's row-major rotation (the
// tf is then no longer followed). Not validated here: GyroFlowReconfigure::set validates.
void applyOnlineCalibration(const OnlineCalibration& msg, GyroFlowParameters& params);

// Serves ~set_parameters on the private node handle. Starts from the parameters the loader read
// (so the loader's defaults are the only ones) and hands every valid change to `apply`, which the
// wrapper uses to replace its parameters under its own lock: nothing else (IMU buffer, frame
// history) is touched, so a change takes effect on the next frame pair. An invalid change is
// refused with a warning naming the parameter, and the previous values are published back.
//
// Threading: `apply` runs on the private node handle's callback queue (the service callback), and
// once inside the constructor; it must not hold a lock the wrapper holds while constructing this.
class GyroFlowReconfigure {
 public:
  using Apply = std::function<void(const GyroFlowParameters&)>;
  GyroFlowReconfigure(const ros::NodeHandle& private_nh, const std::string& log_name,
                      const GyroFlowParameters& loaded, Apply apply);

  // Sets the live-tunable values of `wanted` as if a client had (the online calibration): they are
  // validated, applied and published to the server's clients. Empty when applied, else the problem
  // (nothing changed). Call on the private node handle's callback queue (as the service's).
  std::string set(const GyroFlowParameters& wanted);

 private:
  void callback(GyroFlowConfig& config, uint32_t level);

  std::string log_name_;
  GyroFlowParameters current_;
  Apply apply_;
  boost::recursive_mutex server_mutex_;
  dynamic_reconfigure::Server<GyroFlowConfig> server_;
};

}  // namespace deep_ois
