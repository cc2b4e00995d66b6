// train_stabiliser's cache of each recording's training data (the lens motions from the images,
// the log or the simulator's truth, and the gyro stream): a text file per recording, so that a
// re-run resumes without recomputing the ground truth of finished recordings.
//
// A cache answers only when everything that made it is the same: the bag's content (SHA-256, not
// its name or size), the target, every gyro config value the data depend on (readout, time offset,
// patches, rotation, integration, lens log convention) and the code that computed it. A corrected
// --gyro-config is therefore never answered from the old data.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/ros/bag/stabiliser_training_data.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"

namespace deep_ois {

// What made a recording's data, as named values in a fixed order ("bag_sha256", "target",
// "readout_time", ...; the gyro values under their config names).
using StabiliserCacheKey = std::vector<std::pair<std::string, std::string>>;

// Hashes the bag (throws std::runtime_error naming it when it cannot be read).
StabiliserCacheKey stabiliserCacheKey(const std::string& bag, const GyroFlowParameters& gyro,
                                      const std::string& target);

// The cache file of `bag` in `cache_dir` (named after the bag's absolute path: recordings of
// several cameras often share file names) for `target`.
std::string stabiliserCachePath(const std::string& cache_dir, const std::string& bag,
                                const std::string& target);

// Writes the complete file or nothing (a partial file renamed at the end). Throws
// std::runtime_error naming the file when it cannot be written.
void writeStabiliserCache(const std::string& path, const StabiliserCacheKey& key,
                          const std::string& bag, const StabiliserRecordingData& data);

// The cached data when the file exists, is complete and its key equals `key`; otherwise nothing
// and, in `why_not` (when given), why: "no cache", "incomplete", or what changed ("readout_time
// 0.022 -> 0.012", "the bag's content").
std::optional<StabiliserRecordingData> readStabiliserCache(const std::string& path,
                                                           const StabiliserCacheKey& key,
                                                           const std::string& bag,
                                                           std::string* why_not = nullptr);

}  // namespace deep_ois
