// A flow field as a plain sensor_msgs/Image (32FC2: u, v per pixel), so that rqt_image_view,
// rosbag and other standard tools can show and record it without deep_ois' messages.
#pragma once

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <std_msgs/Header.h>

#include <functional>
#include <opencv2/core.hpp>
#include <string>

namespace deep_ois {

// Advertises `topic` (relative to `nh`) and builds a message only while it has a subscriber.
// `on_subscribers_changed` runs when a subscriber connects or disconnects (the wrapper's connect
// callback: it subscribes its inputs while any output is wanted). A plain publisher, not
// image_transport: compressed transports cannot carry float images.
class FlowImagePublisher {
 public:
  FlowImagePublisher() = default;
  FlowImagePublisher(ros::NodeHandle& nh, const std::string& topic, std::function<void()> on_subscribers_changed);

  bool wanted() const { return publisher_ && publisher_.getNumSubscribers() > 0; }
  // Publishes `flow` (CV_32FC2, grid pixels) with `header` when wanted; copies it once.
  void publish(const std_msgs::Header& header, const cv::Mat& flow) const;

 private:
  ros::Publisher publisher_;
};

}  // namespace deep_ois
