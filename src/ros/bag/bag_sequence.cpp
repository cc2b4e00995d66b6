#include "deep_ois/ros/bag/bag_sequence.h"

#include <deep_ois/LensShiftSample.h>
#include <ros/exception.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Imu.h>
#include <tf2/buffer_core.h>
#include <tf2/exceptions.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {

ImuSampleBuffer BagSequence::imuBuffer() const {
  const double span = imu_samples.empty() ? 1.0 : imu_samples.back().stamp_s - imu_samples.front().stamp_s;
  ImuSampleBuffer buffer(span + 1.0);
  for (const ImuSample& sample : imu_samples) buffer.add(sample);
  return buffer;
}

BagSequence readBagSequence(const std::string& path, const BagSequenceTopics& topics,
                            BagReadFailure on_failure, std::vector<BagFrame>* frames) {
  BagSequence sequence;
  sequence.path = path;
  if (frames) frames->clear();
  auto fail = [&](const std::string& what) { throw std::runtime_error(path + ": " + what); };
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    fail(std::string("cannot open the bag: ") + e.what());
  }
  tf2::BufferCore tf_buffer(ros::Duration(1e6));
  bool have_base = false;
  std::size_t rejected_imu = 0;
  std::string first_imu_problem;
  ros::Time reading;  // bag time of the message being read
  try {
    // Images get their own view on the same bag, merged here by time with the image first at
    // equal stamps: a camera driver publishes the image before its camera_info
    // (image_transport::CameraPublisher), so recorders write it first, and when a chunk closes
    // right after an image its camera_info opens the next chunk. One view over both would order
    // such ties arbitrarily and hop between the two chunks, decompressing each chunk about twice
    // (measured on the simulator's bz2 bags); the bag caches one decompressed chunk.
    rosbag::View others(bag, rosbag::TopicQuery({topics.camera_info, topics.imu,
                                                 topics.frame_pair_truth, topics.lens_shift_log,
                                                 std::string("/tf_static")}));
    std::unique_ptr<rosbag::View> images;
    if (frames) images = std::make_unique<rosbag::View>(bag, rosbag::TopicQuery(topics.image));
    rosbag::View::iterator other = others.begin(), image_it;
    if (images) image_it = images->begin();
    ImuSampleBuffer checker(1e9);  // applies the buffer's sample rules without dropping history
    while (other != others.end() || (images && image_it != images->end())) {
      const bool take_image = images && image_it != images->end() &&
                              (other == others.end() || image_it->getTime() <= other->getTime());
      // A copy: an iterator's message changes when the iterator moves on.
      const rosbag::MessageInstance m = take_image ? *image_it : *other;
      if (take_image) {
        ++image_it;
      } else {
        ++other;
      }
      if (!have_base) {
        sequence.time_base = ros::Time(m.getTime().sec, 0);
        have_base = true;
      }
      reading = m.getTime();
      if (take_image) {
        const auto image = m.instantiate<sensor_msgs::Image>();
        if (!image) fail(topics.image + ": not a sensor_msgs/Image");
        BagFrame frame;
        try {
          decodeBagFrame(*image, frame);
        } catch (const std::runtime_error& e) {
          fail(topics.image + " frame " + std::to_string(frames->size()) + ": " + e.what());
        }
        frames->push_back(std::move(frame));
        continue;
      }
      if (m.getTopic() == topics.imu) {
        const auto imu = m.instantiate<sensor_msgs::Imu>();
        if (!imu) continue;
        const ImuSample sample = toImuSample(*imu, sequence.time_base);
        const ImuAddResult added = checker.add(sample);
        if (!added.accepted()) {
          if (first_imu_problem.empty()) first_imu_problem = added.reason;
          ++rejected_imu;
          continue;
        }
        sequence.imu_frame_id = imu->header.frame_id;
        sequence.imu_samples.push_back(sample);
      } else if (m.getTopic() == topics.camera_info) {
        const auto info = m.instantiate<sensor_msgs::CameraInfo>();
        if (!info) continue;
        if (!sequence.camera) {
          CameraModel camera;
          const std::string problem = toCameraModel(*info, camera);
          if (!problem.empty()) fail(topics.camera_info + ": " + problem);
          sequence.camera = camera;
          sequence.distortion_model = info->distortion_model;
          sequence.camera_frame_id = info->header.frame_id;
        }
        sequence.frame_stamps.push_back(info->header.stamp);
      } else if (m.getTopic() == topics.lens_shift_log) {
        const auto lens = m.instantiate<LensShiftSample>();
        if (!lens) fail(topics.lens_shift_log + ": not a deep_ois/LensShiftSample");
        LensShiftLogSample sample;
        sample.stamp_s = (lens->header.stamp - sequence.time_base).toSec();
        sample.logged = Eigen::Vector2d(lens->x, lens->y);
        if (lens->covariance[0] >= 0.0) {
          sample.covariance = (Eigen::Matrix2d() << lens->covariance[0], lens->covariance[1], lens->covariance[2],
                               lens->covariance[3]).finished();
        }
        sequence.lens_shift_log.push_back(sample);
      } else if (m.getTopic() == topics.frame_pair_truth) {
        const auto truth = m.instantiate<FramePairTruth>();
        if (truth) sequence.truths.push_back(*truth);
      } else {
        const auto tf = m.instantiate<tf2_msgs::TFMessage>();
        if (!tf) continue;
        for (const auto& transform : tf->transforms) tf_buffer.setTransform(transform, "bag", true);
      }
    }
  } catch (const ros::Exception& e) {
    // rosbag::BagException (a chunk that does not decompress) or a serialization error (a message
    // whose bytes are damaged). Reported rather than silently using part of the bag, unless the
    // caller keeps the part before the failure (and reports it itself).
    if (on_failure == BagReadFailure::kThrow) fail(std::string("reading failed: ") + e.what());
    std::ostringstream why;
    why << path << ": the bag is corrupt: reading stopped at bag time " << reading << ", after "
        << sequence.frame_stamps.size() << " camera_info and " << sequence.imu_samples.size()
        << " IMU messages: " << e.what();
    sequence.read_error = why.str();
  }
  if (!sequence.camera) fail("no camera_info on " + topics.camera_info);
  if (rejected_imu > 0) {
    fail(std::to_string(rejected_imu) + " IMU samples on " + topics.imu + " rejected, first: " + first_imu_problem);
  }
  if (sequence.imu_samples.empty()) {
    // The first thing to say: without IMU messages there is no IMU frame to look a transform up
    // for (a wrong topic is the usual cause, so the bag's IMU topics are listed).
    std::string imu_topics;
    for (const rosbag::ConnectionInfo* connection : rosbag::View(bag).getConnections()) {
      if (connection->datatype == "sensor_msgs/Imu" && imu_topics.find(connection->topic + " ") == std::string::npos)
        imu_topics += connection->topic + " ";
    }
    sequence.imu_problem = "no IMU messages on " + topics.imu + " (sensor_msgs/Imu topics in the bag: " +
                           (imu_topics.empty() ? std::string("none") : imu_topics.substr(0, imu_topics.size() - 1)) +
                           ")";
    sequence.imu_to_camera_problem = sequence.imu_problem + ", so no IMU frame to look the IMU -> camera transform up";
  } else if (sequence.imu_frame_id.empty() || sequence.camera_frame_id.empty()) {
    sequence.imu_to_camera_problem =
        std::string(sequence.imu_frame_id.empty() ? "the IMU messages on " + topics.imu
                                                  : "the camera_info messages on " + topics.camera_info) +
        " have an empty frame_id, so no IMU -> camera transform can be looked up in /tf_static";
  } else {
    try {
      const auto transform = tf_buffer.lookupTransform(sequence.camera_frame_id, sequence.imu_frame_id, ros::Time(0));
      const auto& q = transform.transform.rotation;
      sequence.imu_to_camera_rotation = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
    } catch (const tf2::TransformException& e) {
      // No static transform between the two: the caller must supply the rotation.
      sequence.imu_to_camera_problem = "no IMU -> camera transform in /tf_static from the IMU frame '" +
                                       sequence.imu_frame_id + "' to the camera frame '" +
                                       sequence.camera_frame_id + "' (" + e.what() + ")";
    }
  }
  return sequence;
}

}  // namespace deep_ois
