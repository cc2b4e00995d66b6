// The live pipeline's tracking: the online learner's, the per-pair check's and the fusion's, which
// evaluate's fused row reproduces offline. Fewer corners and a smaller KLT than the offline ground
// truth's (the live tracking runs within a CPU budget; ~190 tracks a pair still give ~30 per row
// patch), on frames reduced to at most kLiveTrackingWidthPx wide (FeatureTracker::matchAtWidth).
#pragma once

#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

CornerDetectorOptions liveTrackingCorners();
KltOptions liveTrackingKlt();
// Frames wider than this are tracked on a reduced copy, pixels (~learning_tracking_width's default).
constexpr int kLiveTrackingWidthPx = 480;

// The channel order of a 3- or 4-channel frame (rgb8 / rgba8 against bgr8 / bgra8).
enum class ChannelOrder { kRgb, kBgr };

// A frame as the live tracking reads it: 8-bit gray with the luma weights of its channel order
// (OpenCV's RGB2GRAY on rgb8, as the bag reader makes evaluate's gray frames, so that the live
// compensation and evaluate's fused row track the same pixels); 1-channel frames as toGray8().
// Throws std::invalid_argument as toGray8().
cv::Mat liveTrackingGray(const cv::Mat& frame, ChannelOrder order);

}  // namespace deep_ois
