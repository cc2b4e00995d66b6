#include "deep_ois/ros/bag/bag_static_transforms.h"

#include <ros/exception.h>
#include <ros/message_traits.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>

#include "deep_ois/ros/bag/bag_recovery.h"

namespace deep_ois {
namespace {

// Why tf2's BufferCore::setTransform would refuse the transform; empty when it takes it.
std::string refusal(const geometry_msgs::TransformStamped& t) {
  const std::string frames = "'" + t.header.frame_id + "' -> '" + t.child_frame_id + "'";
  if (t.header.frame_id.empty() || t.child_frame_id.empty()) return "empty frame id in " + frames;
  if (t.header.frame_id == t.child_frame_id) return "a frame's transform to itself, " + frames;
  const auto& q = t.transform.rotation;
  const auto& p = t.transform.translation;
  const double norm = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (!std::isfinite(norm) || !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return "a NaN or infinite value in " + frames;
  }
  if (std::abs(norm - 1.0) > 1e-3) return "a rotation that is not a unit quaternion in " + frames;
  return "";
}

}  // namespace

std::string BagStaticTransforms::summary(const std::string& topic) const {
  std::ostringstream out;
  out << message.transforms.size() << " static transform" << (message.transforms.size() == 1 ? "" : "s");
  std::string pairs;
  for (const auto& t : message.transforms) {
    pairs += (pairs.empty() ? "" : ", ") + t.header.frame_id + " -> " + t.child_frame_id;
  }
  if (!pairs.empty()) out << " (" << pairs << ")";
  out << " from " << messages_read << " message" << (messages_read == 1 ? "" : "s") << " on " << topic;
  if (transforms_skipped > 0) {
    out << "; skipped " << transforms_skipped << " that tf would refuse (first: " << first_skip_reason << ")";
  }
  return out.str();
}

BagStaticTransforms readBagStaticTransforms(const std::string& path, const std::string& topic) {
  const ReadableBag readable(path);
  BagStaticTransforms result;
  result.recovery_note = readable.note();
  std::map<std::string, std::size_t> index_of_child;  // child frame -> index in the message
  try {
    rosbag::Bag bag(readable.path(), rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      const auto tf = m.instantiate<tf2_msgs::TFMessage>();
      if (!tf) {
        throw std::runtime_error(path + ": " + topic + " carries " + m.getDataType() + ", not " +
                                 ros::message_traits::datatype<tf2_msgs::TFMessage>());
      }
      ++result.messages_read;
      for (const geometry_msgs::TransformStamped& t : tf->transforms) {
        const std::string why = refusal(t);
        if (!why.empty()) {
          if (result.transforms_skipped++ == 0) result.first_skip_reason = why;
          continue;
        }
        const auto known = index_of_child.find(t.child_frame_id);
        if (known == index_of_child.end()) {
          index_of_child.emplace(t.child_frame_id, result.message.transforms.size());
          result.message.transforms.push_back(t);
        } else if (t.header.stamp >= result.message.transforms[known->second].header.stamp) {
          result.message.transforms[known->second] = t;
        }
      }
    }
  } catch (const ros::Exception& e) {
    // rosbag::BagException (a chunk that does not decompress) or a damaged message.
    throw std::runtime_error(readable.originalNames(path + ": cannot read " + topic + ": " + e.what()));
  }
  return result;
}

}  // namespace deep_ois
