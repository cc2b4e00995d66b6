// The paper's alignment visualisation: misaligned pixels show as coloured ghosts.
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// The red channel of `rgb_b` over the green and blue channels of `rgb_a` (both CV_8UC3 RGB of one
// size): where the two frames align the result looks grey-natural, elsewhere red/cyan fringes.
cv::Mat ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b);

// The same into `ghost` in one pass: a caller that allocated it (CV_8UC3 of the frames' size, e.g.
// over an outgoing message's buffer) gets the result there; `ghost` may be `rgb_a` itself (then
// only its red channel is replaced). Throws std::invalid_argument on a type or size mismatch.
void ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b, cv::Mat& ghost);

}  // namespace deep_ois
