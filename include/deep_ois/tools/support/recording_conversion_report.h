// What convert_recording prints when it is done, kept here so that its wording is tested: every
// figure says what it counts or what it is a time of, and counts agree with their nouns.
#pragma once

#include <string>
#include <vector>

#include "deep_ois/ros/bag/phone_recording_bag.h"

namespace deep_ois {

// The summary lines of a conversion into `bag_path` (without the tool's prefix): the frames
// written and left out, the first and last frame stamps (the bag's clock) and the span between,
// the IMU and lens-shift messages, the lens log's repairs, and the conversion's wall time
// (`wall_time_s`: reading, pairing and writing).
std::vector<std::string> conversionSummary(const std::string& bag_path, const PhoneRecordingBagStats& stats,
                                           double wall_time_s);

}  // namespace deep_ois
