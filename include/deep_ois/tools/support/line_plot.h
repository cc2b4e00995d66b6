// A minimal line chart drawn with OpenCV (no plotting library on the machine): loss curves.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace deep_ois {

struct PlotSeries {
  std::string label;
  std::vector<double> values;  // y per x = 1, 2, ...; non-finite values are skipped
  cv::Scalar color_bgr;
};

// A white BGR chart of `size` with axes, min/max tick labels, a legend and a title; the y range
// covers every finite value (log10 scale when `log_y` and all values are positive).
cv::Mat drawLinePlot(const std::vector<PlotSeries>& series, const std::string& title, const std::string& x_label,
                     const std::string& y_label, bool log_y = false, cv::Size size = cv::Size(800, 500));

}  // namespace deep_ois
