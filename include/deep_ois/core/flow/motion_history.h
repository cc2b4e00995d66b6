// The recent motion of a camera, summarised for the compensation network: leaky sums of the gyro
// flows of its consecutive frame pairs.
//
// Why: an OIS does not cancel the motion of one frame interval on its own. Its lens follows the
// high-passed integral of the pan/tilt rate (it drifts back to centre with the stabiliser's
// centring filter) and stops at the end of its stroke, so how much of a pair's rotation reaches
// the image depends on how the camera moved over the last fraction of a second. One inter-frame
// gyro flow cannot say whether the lens is free or at its end stop; a few exponentially weighted
// sums of the earlier flows (octave-spaced time constants, a basis for any smooth decaying memory)
// can.
//
// Sum k with time constant tau_k, updated at every pair a -> b of the stream:
//   h_k(t_b) = exp(-(t_b - t_a) / tau_k) * h_k(t_a) + flow(a -> b)
// The network of pair a -> b sees h_k(t_a): the motion before the pair, plus the pair's own flow.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace deep_ois {

class MotionHistory {
 public:
  // time_constants_s: positive and finite, seconds (empty: no history, every call is cheap);
  // grid: the size of the flows (CV_32FC2) it is given. Throws std::invalid_argument otherwise.
  MotionHistory(std::vector<double> time_constants_s, cv::Size grid);

  // The sums just before the pair that starts at frame stamp `stamp_a_ns` (one CV_32FC2 per time
  // constant, pixels of the grid). They restart from zero when the pair does not start where the
  // last added pair ended: the first pair, a dropped frame or pair, a bag that loops. Nothing
  // about the missing motion is known, so zero ("no motion before") is the honest state, and the
  // training set starts every recording the same way.
  const std::vector<cv::Mat>& before(std::int64_t stamp_a_ns);

  // Adds the flow of pair a -> b (stamps in nanoseconds, b after a; CV_32FC2 of the grid size,
  // pixels). Call before() for the same pair first when the network needs its history. Throws
  // std::invalid_argument for a flow of another size or type, or b not after a.
  void add(std::int64_t stamp_a_ns, std::int64_t stamp_b_ns, const cv::Mat& flow);

  void reset();
  // Pairs summed since the last restart (0 = the sums are zero).
  std::size_t pairsSinceReset() const { return pairs_since_reset_; }
  const std::vector<double>& timeConstantsS() const { return time_constants_s_; }
  cv::Size grid() const { return grid_; }

 private:
  std::vector<double> time_constants_s_;
  cv::Size grid_;
  std::vector<cv::Mat> sums_;
  bool has_last_ = false;
  std::int64_t last_stamp_b_ns_ = 0;
  std::size_t pairs_since_reset_ = 0;
};

}  // namespace deep_ois
