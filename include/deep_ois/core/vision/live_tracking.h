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

}  // namespace deep_ois
