#include "deep_ois/tools/support/recorded_flows.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <stdexcept>

#include "deep_ois/GyroFlow.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {

std::map<FramePairStamps, RecordedFlow> readRecordedFlows(const std::string& bag_path, const std::string& topic) {
  std::map<FramePairStamps, RecordedFlow> flows;
  try {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      const GyroFlow::ConstPtr msg = m.instantiate<GyroFlow>();
      if (!msg) throw std::runtime_error("a message on " + topic + " is not a deep_ois/GyroFlow");
      RecordedFlow recorded;
      cv::Mat flow_view;
      const std::string problem = readGyroFlowMsg(*msg, recorded.homographies, flow_view);
      if (!problem.empty()) throw std::runtime_error(topic + " at " + std::to_string(msg->header.stamp.toSec()) + ": " + problem);
      recorded.grid_flow = flow_view.clone();
      flows[{static_cast<std::int64_t>(msg->previous_stamp.toNSec()), static_cast<std::int64_t>(msg->header.stamp.toNSec())}] =
          std::move(recorded);
    }
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(bag_path + ": " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(bag_path + ": " + e.what());
  }
  if (flows.empty()) throw std::runtime_error(bag_path + ": no deep_ois/GyroFlow on " + topic);
  return flows;
}

}  // namespace deep_ois
