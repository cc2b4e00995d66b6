#include "deep_ois/tools/support/line_plot.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace deep_ois {

namespace {
std::string formatNumber(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.4g", value);
  return text;
}
}  // namespace

cv::Mat drawLinePlot(const std::vector<PlotSeries>& series, const std::string& title, const std::string& x_label,
                     const std::string& y_label, bool log_y, cv::Size size) {
  cv::Mat canvas(size, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 80, right = 20, top = 40, bottom = 60;
  const cv::Rect area(left, top, size.width - left - right, size.height - top - bottom);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar black(0, 0, 0), grey(200, 200, 200);

  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::size_t longest = 0;
  bool all_positive = true;
  for (const PlotSeries& s : series) {
    longest = std::max(longest, s.values.size());
    for (double v : s.values) {
      if (!std::isfinite(v)) continue;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      all_positive = all_positive && v > 0.0;
    }
  }
  cv::putText(canvas, title, cv::Point(left, 25), font, 0.6, black, 1, cv::LINE_AA);
  cv::rectangle(canvas, area, black, 1);
  cv::putText(canvas, x_label, cv::Point(left + area.width / 2 - 30, size.height - 15), font, 0.5, black, 1, cv::LINE_AA);
  cv::putText(canvas, y_label, cv::Point(5, top - 8), font, 0.45, black, 1, cv::LINE_AA);
  if (!std::isfinite(lo) || longest == 0) return canvas;

  const bool use_log = log_y && all_positive;
  auto transform = [&](double v) { return use_log ? std::log10(v) : v; };
  double y_lo = transform(lo), y_hi = transform(hi);
  if (y_hi - y_lo < 1e-12) {
    y_lo -= 0.5;
    y_hi += 0.5;
  }
  const double x_max = static_cast<double>(std::max<std::size_t>(longest, 2));
  auto toPixel = [&](std::size_t i, double v) {
    const double fx = (static_cast<double>(i + 1) - 1.0) / (x_max - 1.0);
    const double fy = (transform(v) - y_lo) / (y_hi - y_lo);
    return cv::Point(area.x + static_cast<int>(std::lround(fx * area.width)),
                     area.y + area.height - static_cast<int>(std::lround(fy * area.height)));
  };
  for (int k = 1; k < 4; ++k) {
    const int y = area.y + area.height * k / 4;
    cv::line(canvas, cv::Point(area.x, y), cv::Point(area.x + area.width, y), grey, 1);
  }
  cv::putText(canvas, formatNumber(hi), cv::Point(5, area.y + 5), font, 0.4, black, 1, cv::LINE_AA);
  cv::putText(canvas, formatNumber(lo), cv::Point(5, area.y + area.height), font, 0.4, black, 1, cv::LINE_AA);
  cv::putText(canvas, "1", cv::Point(area.x, area.y + area.height + 18), font, 0.4, black, 1, cv::LINE_AA);
  cv::putText(canvas, std::to_string(longest), cv::Point(area.x + area.width - 20, area.y + area.height + 18), font,
              0.4, black, 1, cv::LINE_AA);

  int legend_y = area.y + 20;
  for (const PlotSeries& s : series) {
    cv::Point previous(-1, -1);
    for (std::size_t i = 0; i < s.values.size(); ++i) {
      if (!std::isfinite(s.values[i])) {
        previous = cv::Point(-1, -1);
        continue;
      }
      const cv::Point p = toPixel(i, s.values[i]);
      if (previous.x >= 0) cv::line(canvas, previous, p, s.color_bgr, 2, cv::LINE_AA);
      cv::circle(canvas, p, 2, s.color_bgr, cv::FILLED, cv::LINE_AA);
      previous = p;
    }
    cv::line(canvas, cv::Point(area.x + area.width - 220, legend_y - 4),
             cv::Point(area.x + area.width - 190, legend_y - 4), s.color_bgr, 2);
    cv::putText(canvas, s.label, cv::Point(area.x + area.width - 185, legend_y), font, 0.45, black, 1, cv::LINE_AA);
    legend_y += 20;
  }
  return canvas;
}

}  // namespace deep_ois
