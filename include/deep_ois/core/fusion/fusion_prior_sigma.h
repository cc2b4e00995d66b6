// The fused motion's prior sigma (MotionPrior::sigma_px) from the compensation's recent per-pair
// checks (core/vision/compensation_check.h): the median model residual of the last usable checks,
// never below a floor (the residual holds the tracks' noise), a default before the first usable
// check. One rule for the live compensation and evaluate's fused row, so that both give a pair the
// same sigma. Pure C++: no ROS, no OpenCV calls.
#pragma once

#include <cstddef>
#include <deque>
#include <string>

#include "deep_ois/core/vision/compensation_check.h"

namespace deep_ois {

struct FusionPriorSigmaOptions {
  std::size_t recent_checks = 10;  // the median is over this many last usable checks
  double initial_sigma_px = 0.5;   // before the first usable check, pixels
  double min_sigma_px = 0.1;       // the least sigma taken from the checks, pixels

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// Single-threaded: the caller serialises add() and sigmaPx().
class FusionPriorSigma {
 public:
  // Throws std::invalid_argument naming the bad option.
  explicit FusionPriorSigma(FusionPriorSigmaOptions options = {});

  // A pair's check, after the pair was fused (it counts for the next pairs). An unusable check, or
  // one whose model residual is not finite, changes nothing.
  void add(const CompensationCheck& check);
  // The sigma for the next pair, pixels.
  double sigmaPx() const;
  // Usable checks held (at most options.recent_checks).
  std::size_t checks() const { return recent_residuals_px_.size(); }
  // Forgets the checks (another recording, a restarted stream): back to the initial sigma.
  void clear() { recent_residuals_px_.clear(); }

  const FusionPriorSigmaOptions& options() const { return options_; }

 private:
  FusionPriorSigmaOptions options_;
  std::deque<double> recent_residuals_px_;  // newest last
};

}  // namespace deep_ois
