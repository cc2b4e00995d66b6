// Images of the evaluator, composed with OpenCV: ghost-image grids (the paper's visual check: the
// red channel of frame b, brought onto frame a by a method's motion, over frame a; grey where
// aligned, red/cyan fringes where not). Its bar charts are drawn by matplotlib from
// evaluation.csv (evaluation_report.h).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace deep_ois {

// The centre 1/factor of an image magnified `factor` times (nearest neighbour, so one-pixel
// fringes stay sharp): the same size as the input. factor 1 returns the image. Throws
// std::invalid_argument for factor < 1.
cv::Mat magnifyCentre(const cv::Mat& image, int factor);

// One method's ghost of a frame pair.
struct GhostPanel {
  std::string method;
  cv::Mat ghost_rgb;         // CV_8UC3 RGB, camera size
  double distance_px = 0.0;  // the pair's scored (capped) geometry distance
  bool failed = false;       // no estimate: the panel shows the unaligned ghost
  bool capped = false;       // its own distance was above identity (the ghost shows its own motion)
};

// The ghosts of one frame pair, one panel per method that scores it.
struct GhostSample {
  std::string category;
  std::string label;  // e.g. "RE_2000.bag, pair 35 (1594117812.123456789 -> ...)"
  std::vector<GhostPanel> panels;
};

// A grid for the samples: one row per sample, one column per entry of `methods` (blank where a
// sample has no panel of that method), the method names as column headers, each row titled with
// its label and each panel captioned with its distance. Returns CV_8UC3 RGB; empty without
// samples.
cv::Mat drawGhostGrid(const std::string& title, const std::vector<GhostSample>& samples,
                      const std::vector<std::string>& methods);

}  // namespace deep_ois
