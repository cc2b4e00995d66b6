#include "deep_ois/ros/bag/bag_frame_reader.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>

#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {

void decodeBagFrame(const sensor_msgs::Image& image, BagFrame& frame) {
  const std::string problem = validateImage(image);
  if (!problem.empty()) throw std::runtime_error(problem);
  try {
    // toCvCopy: the result owns its pixels (the message buffer goes with the bag iterator).
    frame.rgb = cv_bridge::toCvCopy(image, sensor_msgs::image_encodings::RGB8)->image;
  } catch (const cv_bridge::Exception& e) {
    throw std::runtime_error(std::string("cannot decode the image: ") + e.what());
  }
  frame.stamp = image.header.stamp;
  frame.frame_id = image.header.frame_id;
  cv::cvtColor(frame.rgb, frame.gray, cv::COLOR_RGB2GRAY);
}

BagFrameReader::BagFrameReader(const std::string& path, const std::string& image_topic)
    : path_(path), topic_(image_topic) {
  try {
    bag_.open(path, rosbag::bagmode::Read);
    view_ = std::make_unique<rosbag::View>(bag_, rosbag::TopicQuery(image_topic));
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(path + ": cannot open the bag: " + e.what());
  }
  frame_count_ = view_->size();
  if (frame_count_ == 0) throw std::runtime_error(path + ": no messages on " + image_topic);
  it_ = view_->begin();
}

bool BagFrameReader::next(BagFrame& frame) {
  const std::string where = path_ + ": " + topic_ + " after " + std::to_string(frames_read_) + " frames: ";
  try {
    if (it_ == view_->end()) return false;
    const sensor_msgs::ImageConstPtr image = it_->instantiate<sensor_msgs::Image>();
    if (!image) throw std::runtime_error("not a sensor_msgs/Image");
    decodeBagFrame(*image, frame);
    ++it_;
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(where + "the bag is corrupt: " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(where + e.what());
  }
  ++frames_read_;
  return true;
}

std::size_t indexedFramePairCount(const std::string& path, const std::string& image_topic) {
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    const std::size_t frames = rosbag::View(bag, rosbag::TopicQuery(image_topic)).size();
    return frames > 0 ? frames - 1 : 0;
  } catch (const std::exception&) {
    return 0;
  }
}

}  // namespace deep_ois
