#include "deep_ois/tools/support/evaluation_plots.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace deep_ois {
namespace {

const cv::Scalar kBlack(0, 0, 0), kWhite(255, 255, 255);
const int kFont = cv::FONT_HERSHEY_SIMPLEX;

int textWidth(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline).width;
}

std::string formatPx(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3f", value);
  return text;
}

// Splits a header into at most two lines that fit `width` pixels (at a comma or space).
std::vector<std::string> wrap(const std::string& text, double scale, int width) {
  if (textWidth(text, scale) <= width) return {text};
  for (std::size_t cut = text.size(); cut-- > 1;) {
    if (text[cut] != ' ') continue;
    const std::string first = text.substr(0, cut);
    if (textWidth(first, scale) <= width) return {first, text.substr(cut + 1)};
  }
  return {text};
}

}  // namespace

cv::Mat magnifyCentre(const cv::Mat& image, int factor) {
  if (factor < 1) throw std::invalid_argument("magnifyCentre: factor must be >= 1");
  if (factor == 1 || image.empty()) return image;
  const cv::Size crop(std::max(1, image.cols / factor), std::max(1, image.rows / factor));
  const cv::Rect centre((image.cols - crop.width) / 2, (image.rows - crop.height) / 2, crop.width,
                        crop.height);
  cv::Mat magnified;
  cv::resize(image(centre), magnified, image.size(), 0.0, 0.0, cv::INTER_NEAREST);
  return magnified;
}

cv::Mat drawGhostGrid(const std::string& title, const std::vector<GhostSample>& samples,
                      const std::vector<std::string>& methods) {
  if (samples.empty() || methods.empty()) return cv::Mat();
  cv::Size panel_size;
  for (const GhostSample& sample : samples) {
    for (const GhostPanel& panel : sample.panels) {
      if (!panel.ghost_rgb.empty()) panel_size = panel.ghost_rgb.size();
    }
  }
  if (panel_size.empty()) return cv::Mat();
  const int gap = 4, title_height = 34, header_height = 40, row_title_height = 22,
            caption_height = 20;
  const int columns = static_cast<int>(methods.size());
  const int width = columns * (panel_size.width + gap) + gap;
  const int row_height = row_title_height + panel_size.height + caption_height;
  const int height =
      title_height + header_height + static_cast<int>(samples.size()) * row_height + gap;
  cv::Mat grid(height, width, CV_8UC3, kWhite);
  cv::putText(grid, title, cv::Point(gap + 4, 24), kFont, 0.65, kBlack, 1, cv::LINE_AA);
  for (int c = 0; c < columns; ++c) {
    const int x = gap + c * (panel_size.width + gap);
    const std::vector<std::string> lines = wrap(methods[c], 0.5, panel_size.width - 8);
    for (std::size_t l = 0; l < lines.size(); ++l) {
      cv::putText(grid, lines[l], cv::Point(x + 4, title_height + 14 + 17 * static_cast<int>(l)),
                  kFont, 0.5, kBlack, 1, cv::LINE_AA);
    }
  }
  for (std::size_t r = 0; r < samples.size(); ++r) {
    const int y = title_height + header_height + static_cast<int>(r) * row_height;
    cv::putText(grid, samples[r].label, cv::Point(gap + 4, y + 16), kFont, 0.45, kBlack, 1,
                cv::LINE_AA);
    for (int c = 0; c < columns; ++c) {
      const auto panel = std::find_if(samples[r].panels.begin(), samples[r].panels.end(),
                                      [&](const GhostPanel& p) { return p.method == methods[c]; });
      if (panel == samples[r].panels.end() || panel->ghost_rgb.size() != panel_size ||
          panel->ghost_rgb.type() != CV_8UC3) {
        continue;
      }
      const int x = gap + c * (panel_size.width + gap);
      panel->ghost_rgb.copyTo(
          grid(cv::Rect(x, y + row_title_height, panel_size.width, panel_size.height)));
      const std::string caption = formatPx(panel->distance_px) + " px" +
                                  (panel->failed   ? " (no estimate: identity)"
                                   : panel->capped ? " (capped at identity)"
                                                   : "");
      cv::putText(grid, caption, cv::Point(x + 4, y + row_title_height + panel_size.height + 15),
                  kFont, 0.45, panel->failed ? cv::Scalar(200, 0, 0) : kBlack, 1, cv::LINE_AA);
    }
  }
  return grid;
}

}  // namespace deep_ois
