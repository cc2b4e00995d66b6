// Flows the live nodelets published, read back from a `rosbag record` of their topics: the
// evaluator scores them beside its offline rows to prove that the live system and the offline
// path give the same numbers.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include <opencv2/core.hpp>

namespace deep_ois {

// deep_ois/GyroFlow messages of `topic`, keyed by the stamp of frame b (ns since the epoch): the
// CV_32FC2 grid flow of each (a copy). Throws std::runtime_error naming the bag when it cannot be
// read, a message is malformed, or the topic holds no GyroFlow.
std::map<std::int64_t, cv::Mat> readRecordedFlows(const std::string& bag_path, const std::string& topic);

}  // namespace deep_ois
