#include "deep_ois/core/vision/live_tracking.h"

#include <opencv2/imgproc.hpp>

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

cv::Mat liveTrackingGray(const cv::Mat& frame, ChannelOrder order) {
  if (frame.depth() != CV_8U || (frame.channels() != 3 && frame.channels() != 4)) return toGray8(frame);
  cv::Mat gray;
  if (frame.channels() == 3) {
    cv::cvtColor(frame, gray, order == ChannelOrder::kRgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
  } else {
    cv::cvtColor(frame, gray, order == ChannelOrder::kRgb ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY);
  }
  return gray;
}

}  // namespace deep_ois
