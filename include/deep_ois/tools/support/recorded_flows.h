// Flows the live nodelets published, read back from a `rosbag record` of their topics: the
// evaluator scores them beside its offline rows to prove that the live system and the offline
// path give the same numbers.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace deep_ois {

// A recorded flow's frame pair: stamps of frames a and b, ns since the epoch. A live nodelet that
// lost a frame pairs its neighbours, so both stamps identify the pair.
using FramePairStamps = std::pair<std::int64_t, std::int64_t>;

// What one recorded deep_ois/GyroFlow carries: the row-patch homographies (camera pixels) and the
// CV_32FC2 grid flow (a copy).
struct RecordedFlow {
  std::vector<Eigen::Matrix3d> homographies;
  cv::Mat grid_flow;
};

// deep_ois/GyroFlow messages of `topic`, keyed by their frame pair. Throws std::runtime_error naming the bag when it cannot be
// read, a message is malformed, or the topic holds no GyroFlow.
std::map<FramePairStamps, RecordedFlow> readRecordedFlows(const std::string& bag_path, const std::string& topic);

}  // namespace deep_ois
