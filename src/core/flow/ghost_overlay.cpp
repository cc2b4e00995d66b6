#include "deep_ois/core/flow/ghost_overlay.h"

#include <stdexcept>

namespace deep_ois {

cv::Mat ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b) {
  if (rgb_a.type() != CV_8UC3 || rgb_b.type() != CV_8UC3 || rgb_a.size() != rgb_b.size()) {
    throw std::invalid_argument("ghostOverlay: need two CV_8UC3 images of the same size");
  }
  cv::Mat ghost = rgb_a.clone();
  const int from_to[] = {0, 0};  // channel 0 (red) of b -> channel 0 of the result
  cv::mixChannels(&rgb_b, 1, &ghost, 1, from_to, 1);
  return ghost;
}

}  // namespace deep_ois
