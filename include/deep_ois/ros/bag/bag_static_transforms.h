// The static transforms a bag holds, merged into one message to publish on /tf_static.
//
// A replay gets its IMU -> camera mount from the bag's /tf_static, which a recorder writes once,
// at the start. `rosbag play` publishes it only when it plays that first message; started past it
// (--start), it publishes it after its delay on a publisher it advertises only then, so the mount
// reaches tf after the first data and their pairs had no transform (issue 14, defect 9; a short
// replay lost every pair). A bag whose /tf_static connection lost its latching flag
// (rewritten by a tool that drops connection headers) has it published once, unlatched, so that a
// listener started later than the player, as on a slow first start, misses it too. And when two
// static publishers were recorded, only the last latched message reaches a late subscriber.
// Reading the transforms from the bag file and publishing them latched, as one message, takes
// the player's timing out of it: launch/replay.launch runs the bag_static_transforms tool.
#pragma once

#include <tf2_msgs/TFMessage.h>

#include <cstddef>
#include <string>

namespace deep_ois {

struct BagStaticTransforms {
  // One transform per child frame (tf allows a child only one parent): the newest by header
  // stamp, the later in the bag on a tie. In order of the child frame's first appearance.
  tf2_msgs::TFMessage message;
  std::size_t messages_read = 0;        // messages on the topic
  std::size_t transforms_skipped = 0;   // transforms tf would refuse (empty frame id, bad rotation)
  std::string first_skip_reason;        // the first of them, naming the frames
  std::string recovery_note;            // non-empty when the bag had no index and was scanned

  // "N static transforms (parent -> child, ...) from M messages on TOPIC"; the skips, if any.
  std::string summary(const std::string& topic) const;
};

// Reads every message on `topic` (tf2_msgs/TFMessage) of the bag at `path` and merges their
// transforms. A bag without index (cut short, writer killed) is scanned up to its damage. Throws
// std::runtime_error naming the file when it is no readable bag, or naming the topic when it
// carries another message type. A bag without the topic gives an empty message.
BagStaticTransforms readBagStaticTransforms(const std::string& path, const std::string& topic = "/tf_static");

}  // namespace deep_ois
