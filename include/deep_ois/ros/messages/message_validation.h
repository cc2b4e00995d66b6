// Field-by-field checks of the package's own messages, for what comes in (a GyroFlow from another
// node, a bag, a fuzzer) and what goes out (every GyroFlow and CompensationPairCheck a nodelet
// publishes is checked before publishing, so a non-finite value passed through from an input or
// made by a model never reaches a subscriber).
#pragma once

#include <deep_ois/CompensationPairCheck.h>
#include <deep_ois/GyroFlow.h>

#include <string>

namespace deep_ois {

// Empty when every field of `msg` is consistent and finite, otherwise one sentence naming the
// first field that is not (and its value or sizes):
// - stamps: header.stamp not zero, previous_stamp before it;
// - sizes: image_width/height > 0, patch_count > 0, 9 homography values per patch, 3
//   angular_velocity values per angular_velocity_times entry, the times increasing;
// - every float64 finite (homographies with H[2][2] != 0, K with positive fx and fy, D,
//   readout_time >= 0, time_offset, patch_time_fraction in [0, 1], imu_to_camera_rotation, the
//   angular velocity and its times);
// - the flow: a 32FC2 image of positive size whose step and data hold it, every value finite.
std::string gyroFlowProblem(const GyroFlow& msg);

// The same for a CompensationPairCheck: stamps as above, confidence in [0, 1], inliers <= tracks,
// and both residuals finite and >= 0 when `usable` (NaN when not usable is the message's "no
// verdict", as CompensationPairCheck.msg says).
std::string compensationPairCheckProblem(const CompensationPairCheck& msg);

// Empty when a 32FC2 (or any 32F) image holds only finite values, else a sentence saying where the
// first non-finite value is. Other encodings: empty (integer pixels are always finite).
std::string nonFiniteFloatImageProblem(const sensor_msgs::Image& image);

}  // namespace deep_ois
