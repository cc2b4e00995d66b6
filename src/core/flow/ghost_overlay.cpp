#include "deep_ois/core/flow/ghost_overlay.h"

#include <stdexcept>

namespace deep_ois {

cv::Mat ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b) {
  cv::Mat ghost;
  ghostOverlay(rgb_a, rgb_b, ghost);
  return ghost;
}

void ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b, cv::Mat& ghost) {
  if (rgb_a.type() != CV_8UC3 || rgb_b.type() != CV_8UC3 || rgb_a.size() != rgb_b.size()) {
    throw std::invalid_argument("ghostOverlay: need two CV_8UC3 images of the same size");
  }
  ghost.create(rgb_a.size(), CV_8UC3);
  if (ghost.data == rgb_a.data) {
    const int red_only[] = {0, 0};  // red of b -> red of the result; green and blue stay a's
    cv::mixChannels(&rgb_b, 1, &ghost, 1, red_only, 1);
    return;
  }
  // Sources listed as {rgb_b, rgb_a}: channels 0-2 are b's, 3-5 a's.
  const cv::Mat sources[] = {rgb_b, rgb_a};
  const int from_to[] = {0, 0, 4, 1, 5, 2};
  cv::mixChannels(sources, 2, &ghost, 1, from_to, 3);
}

}  // namespace deep_ois
