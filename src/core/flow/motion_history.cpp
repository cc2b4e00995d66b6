#include "deep_ois/core/flow/motion_history.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace deep_ois {

MotionHistory::MotionHistory(std::vector<double> time_constants_s, cv::Size grid)
    : time_constants_s_(std::move(time_constants_s)), grid_(grid) {
  if (grid_.width < 1 || grid_.height < 1) throw std::invalid_argument("motion history: the grid is empty");
  for (double tau : time_constants_s_) {
    if (!(tau > 0.0) || !std::isfinite(tau)) {
      throw std::invalid_argument("motion history: time constants must be positive seconds (got " +
                                  std::to_string(tau) + ")");
    }
  }
  reset();
}

void MotionHistory::reset() {
  sums_.assign(time_constants_s_.size(), cv::Mat());
  for (cv::Mat& sum : sums_) sum = cv::Mat::zeros(grid_, CV_32FC2);
  has_last_ = false;
  pairs_since_reset_ = 0;
}

const std::vector<cv::Mat>& MotionHistory::before(std::int64_t stamp_a_ns) {
  if (has_last_ && stamp_a_ns != last_stamp_b_ns_) reset();
  return sums_;
}

void MotionHistory::add(std::int64_t stamp_a_ns, std::int64_t stamp_b_ns, const cv::Mat& flow) {
  if (flow.type() != CV_32FC2 || flow.size() != grid_) {
    throw std::invalid_argument("motion history: the flow must be CV_32FC2 of " + std::to_string(grid_.width) + "x" +
                                std::to_string(grid_.height) + " (got " + std::to_string(flow.cols) + "x" +
                                std::to_string(flow.rows) + ")");
  }
  if (stamp_b_ns <= stamp_a_ns) throw std::invalid_argument("motion history: frame b must come after frame a");
  if (has_last_ && stamp_a_ns != last_stamp_b_ns_) reset();
  const double interval_s = 1e-9 * static_cast<double>(stamp_b_ns - stamp_a_ns);
  for (std::size_t k = 0; k < sums_.size(); ++k) {
    const double decay = std::exp(-interval_s / time_constants_s_[k]);
    cv::addWeighted(sums_[k], decay, flow, 1.0, 0.0, sums_[k]);
  }
  has_last_ = true;
  last_stamp_b_ns_ = stamp_b_ns;
  ++pairs_since_reset_;
}

}  // namespace deep_ois
