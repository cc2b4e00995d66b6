#include "deep_ois/ros/live/flow_image_publisher.h"

#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>

#include <boost/make_shared.hpp>
#include <cstring>

namespace deep_ois {

FlowImagePublisher::FlowImagePublisher(ros::NodeHandle& nh, const std::string& topic,
                                       std::function<void()> on_subscribers_changed) {
  auto changed = [on_subscribers_changed](const ros::SingleSubscriberPublisher&) { on_subscribers_changed(); };
  publisher_ = nh.advertise<sensor_msgs::Image>(topic, 5, changed, changed);
}

void FlowImagePublisher::publish(const std_msgs::Header& header, const cv::Mat& flow) const {
  if (!wanted()) return;
  CV_Assert(flow.type() == CV_32FC2);
  auto msg = boost::make_shared<sensor_msgs::Image>();
  msg->header = header;
  msg->width = static_cast<uint32_t>(flow.cols);
  msg->height = static_cast<uint32_t>(flow.rows);
  msg->encoding = sensor_msgs::image_encodings::TYPE_32FC2;
  msg->is_bigendian = false;
  msg->step = static_cast<uint32_t>(flow.cols * flow.elemSize());
  msg->data.resize(static_cast<std::size_t>(msg->step) * flow.rows);
  for (int y = 0; y < flow.rows; ++y) {
    std::memcpy(&msg->data[static_cast<std::size_t>(y) * msg->step], flow.ptr(y), msg->step);
  }
  publisher_.publish(msg);
}

}  // namespace deep_ois
