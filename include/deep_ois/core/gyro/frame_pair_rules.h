// The gyro flow's frame pairing and wait rules, without ROS: whether two consecutive frames make a
// pair, how long a frame waits for the IMU samples and the lens-shift log that cover it, and when a
// pair spans lost frames. GyroFlowRos asks these for every pending frame and does the I/O (the
// warnings, the counts, rendering, publishing).
#pragma once

#include <cstddef>
#include <deque>

#include "deep_ois/core/gyro/orientation_integrator.h"

namespace deep_ois {

struct FramePairLimits {
  double max_frame_interval_s = 0.2;   // ~max_frame_interval: frames further apart are not paired
  double imu_wait_timeout_s = 0.5;     // ~imu_wait_timeout
  double lens_wait_timeout_s = 0.5;    // ~lens_shift_wait_timeout
};

enum class FramePairCheck {
  kPair,
  kTooFarApart,    // further apart than max_frame_interval_s
  kCameraChanged,  // the frames' camera models differ
};

// What to do with a frame whose data (IMU samples, lens log) does not cover its pair yet.
enum class FrameWait { kProceed, kWait, kGiveUp };

class FramePairRules {
 public:
  explicit FramePairRules(const FramePairLimits& limits = {});
  void setLimits(const FramePairLimits& limits) { limits_ = limits; }
  const FramePairLimits& limits() const { return limits_; }

  // Whether frame a (stamp `previous_s`) and frame b (`frame_s`, seconds) make a pair.
  FramePairCheck check(double previous_s, double frame_s, bool same_camera) const;

  // The IMU's answer for the pair was `status`. A frame waits while its samples may still come
  // (not yet there, or an empty buffer) and either the frame has waited less than the timeout or
  // IMU messages still arrive (a frame whose samples are queued behind a stalled callback thread on
  // a loaded machine keeps waiting; the caller bounds the number of pending frames). `waited_s`:
  // since the frame arrived; `imu_quiet_s`: since the last IMU message arrived (any < 0: none
  // yet, counted as waited_s). kProceed when the status is kOk.
  FrameWait imuWait(IntegrationStatus status, double waited_s, double imu_quiet_s) const;
  // Whether `status` is one that more IMU data could still resolve.
  static bool imuMayStillCome(IntegrationStatus status);

  // The lens-shift log (a phone delivers it with the capture result, after the frame): the frame
  // waits while the log ends before `needed_end_s` and both the frame's wait and the log's silence
  // (`log_quiet_s`) are under the timeout; kProceed otherwise (the caller then uses the log if it
  // covers the pair, else the gyro alone). The wait is bounded per frame, so a log on a wrong
  // clock delays pairs but never drops them.
  FrameWait lensLogWait(double log_newest_s, double needed_end_s, double waited_s, double log_quiet_s) const;

  // A frame became frame a of the next pair; `interval_s` from the frame before it (the history
  // of the typical interval).
  void accepted(double interval_s);
  // Median of the recent intervals, seconds; 0 until three are known.
  double typicalIntervalS() const;
  // How many typical intervals a pair of `interval_s` spans when it is longer than 1.5 of them (a
  // frame was lost in between: still a right flow, but said); 0 for a usual pair or while the
  // typical interval is unknown.
  int spannedIntervals(double interval_s) const;
  // Forgets the history (a reset: time went back, no subscriber).
  void clear() { intervals_s_.clear(); }

 private:
  FramePairLimits limits_;
  std::deque<double> intervals_s_;  // of consecutive accepted frames, newest last
};

}  // namespace deep_ois
