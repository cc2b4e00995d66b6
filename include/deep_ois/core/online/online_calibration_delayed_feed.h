// The online calibration fed live: a pair's gyro stream, as the gyro flow sends it, ends at the
// pair's last row, but the estimator fits only once its gyro reaches past the newest pair by its
// search half-width (any offset the coarse search may find must be covered), so a pair added with
// its own gyro never makes a fit due. This feed adds each pair's gyro at once and holds its tracks
// until a later pair's gyro covers them by `coverage_s`, then adds them and runs the due work (a
// few pairs, ~0.15 s, late). feedTrackedPair (online_calibration_feed.h) suits a replay that feeds
// the gyro ahead; this one the live nodelet.
//
// Not thread-safe: the caller that owns the estimator feeds it. Pure Eigen: no ROS.
#pragma once

#include <deque>
#include <vector>

#include "deep_ois/core/online/online_calibration_estimator.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"

namespace deep_ois {

class DelayedCalibrationFeed {
 public:
  // `coverage_s`: how far past a pair's frame b (camera clock, plus the estimate's offset) the gyro
  // must reach before the pair is added: the estimator's OnlineCalibrationOptions::first_search_s
  // plus 0.05 s and a margin (kCoverageMarginS).
  explicit DelayedCalibrationFeed(double coverage_s) : coverage_s_(coverage_s) {}
  static constexpr double kCoverageMarginS = 0.01;
  static double coverageFor(const OnlineCalibrationOptions& options) {
    return options.first_search_s + 0.05 + kCoverageMarginS;
  }

  // Adds the pair's gyro (raw IMU samples: R_cam_imu^T times the camera-frame rates, R from
  // pair.timing) to `estimator`, queues the pair's tracks (none when untracked: it still adds
  // time), adds the queued pairs the gyro now covers and runs the estimator's due work. Returns the
  // pairs added by this call (e.g. to score them); *changed: whether the calibration in use changed.
  // A pair whose frame b is before the last one's (time went back without clear()) starts another
  // timeline: the queued pairs are dropped and the estimator's timeline restarted (it ignores older
  // pairs and gyro otherwise); one with the same frame b (a repeat) is dropped. Both are counted.
  std::vector<OnlineCalibrationPair> feed(const OnlineFramePair& pair, OnlineCalibrationEstimator& estimator,
                                          bool* changed);
  // Time went back (the caller restarts the estimator's timeline): the queued pairs belong to the
  // other timeline and are dropped (counted), and the gyro seen so far no longer covers anything.
  void clear();
  std::size_t waiting() const { return waiting_.size(); }
  // Pairs never added to the estimator: queued when time went back, or repeats.
  std::size_t dropped() const { return dropped_; }
  std::size_t repeats() const { return repeats_; }  // of which: repeated pairs

 private:
  double coverage_s_;
  std::deque<OnlineCalibrationPair> waiting_;
  double gyro_end_s_ = -1e300;  // IMU clock: the newest sample added
  double last_stamp_b_s_ = -1e300;  // camera clock: frame b of the newest pair fed
  std::size_t dropped_ = 0, repeats_ = 0;
};

}  // namespace deep_ois
