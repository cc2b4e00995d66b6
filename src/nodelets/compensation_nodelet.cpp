// Nodelet shell of deep_ois::CompensationRos.
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "deep_ois/ros/live/compensation_ros.h"

namespace deep_ois {

class CompensationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      compensation_ = std::make_unique<CompensationRos>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {
      // A missing or incompatible model is fatal: say which file and why, and fail the load.
      NODELET_FATAL("%s", e.what());
      throw;
    }
  }

  std::unique_ptr<CompensationRos> compensation_;
};

}  // namespace deep_ois

PLUGINLIB_EXPORT_CLASS(deep_ois::CompensationNodelet, nodelet::Nodelet)
