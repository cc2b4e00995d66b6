#include "deep_ois/core/vision/live_tracking.h"

namespace deep_ois {

CornerDetectorOptions liveTrackingCorners() {
  CornerDetectorOptions corners;
  corners.min_corners_per_cell = 4;
  corners.max_corners_per_cell = 4;
  return corners;
}

KltOptions liveTrackingKlt() {
  KltOptions klt;
  klt.window_size_px = 15;
  klt.pyramid_levels = 2;
  klt.max_iterations = 20;
  return klt;
}

}  // namespace deep_ois
