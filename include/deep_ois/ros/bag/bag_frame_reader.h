// Streams the frames of one camera topic of a rosbag in order, decoded for OpenCV, for offline
// tools that need the images themselves (feature tracking, image baselines).
#pragma once

#include <ros/time.h>
#include <sensor_msgs/Image.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <memory>
#include <opencv2/core.hpp>
#include <string>

namespace deep_ois {

struct BagFrame {
  ros::Time stamp;
  std::string frame_id;
  cv::Mat rgb;   // CV_8UC3, RGB order
  cv::Mat gray;  // CV_8UC1
};

// Decodes one image message into `frame` (RGB and grey copies that own their data). Throws
// std::runtime_error naming the problem (invalid header, undecodable encoding) but not the bag.
void decodeBagFrame(const sensor_msgs::Image& image, BagFrame& frame);

class BagFrameReader {
 public:
  // Throws std::runtime_error naming the bag when it cannot be opened (missing, unindexed after
  // a crash, not a bag) or has no message on `image_topic`.
  BagFrameReader(const std::string& path, const std::string& image_topic);

  // The next frame in bag order; false after the last. Throws std::runtime_error naming the bag,
  // the topic and how many frames were read when a chunk is corrupt or an image cannot be
  // decoded; frames already returned stay valid.
  bool next(BagFrame& frame);

  std::size_t frameCount() const { return frame_count_; }  // from the bag's index
  std::size_t framesRead() const { return frames_read_; }

 private:
  std::string path_;
  std::string topic_;
  rosbag::Bag bag_;
  std::unique_ptr<rosbag::View> view_;
  rosbag::View::iterator it_;
  std::size_t frame_count_ = 0;
  std::size_t frames_read_ = 0;
};

// Frame pairs on `image_topic` from the bag's index only (cheap: no message is read), for progress
// bars. A bag that cannot be opened counts 0; the reader that follows reports it.
std::size_t indexedFramePairCount(const std::string& path, const std::string& image_topic);

}  // namespace deep_ois
