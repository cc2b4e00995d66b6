// Nodelet shell of deep_ois::GyroFlowRos.
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "deep_ois/ros/live/gyro_flow_ros.h"

namespace deep_ois {

class GyroFlowNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      gyro_flow_ = std::make_unique<GyroFlowRos>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {
      NODELET_FATAL("%s", e.what());
      throw;
    }
  }

  std::unique_ptr<GyroFlowRos> gyro_flow_;
};

}  // namespace deep_ois

PLUGINLIB_EXPORT_CLASS(deep_ois::GyroFlowNodelet, nodelet::Nodelet)
