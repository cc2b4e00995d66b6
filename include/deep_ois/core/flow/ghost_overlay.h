// The paper's alignment visualisation: misaligned pixels show as coloured ghosts.
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// The red channel of `rgb_b` over the green and blue channels of `rgb_a` (both CV_8UC3 RGB of one
// size): where the two frames align the result looks grey-natural, elsewhere red/cyan fringes.
cv::Mat ghostOverlay(const cv::Mat& rgb_a, const cv::Mat& rgb_b);

}  // namespace deep_ois
