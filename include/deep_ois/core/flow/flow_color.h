// Colour coding of a dense flow field for display.
#pragma once

#include <opencv2/core.hpp>

namespace deep_ois {

// Hue = flow direction (red = right, then counter-clockwise on screen through yellow = up...),
// value = magnitude / max_magnitude_px (saturating at 1), full saturation. `flow` is CV_32FC2;
// returns CV_8UC3 in RGB order. max_magnitude_px <= 0 scales by the largest magnitude in the field
// (a still field is black).
cv::Mat colorizeFlow(const cv::Mat& flow, double max_magnitude_px = 0.0);

// The same into `rgb`: a caller that allocated it (CV_8UC3 of the flow's size, e.g. over an
// outgoing message's buffer) gets the result there.
void colorizeFlow(const cv::Mat& flow, double max_magnitude_px, cv::Mat& rgb);

}  // namespace deep_ois
