// Whether a stream's stamps agree with the clock that reads them (ROS time). Stamps decades from
// ros::Time::now() are not a slow pipeline but two clocks: `rosbag play --clock` while use_sim_time
// is false (bag stamps, wall clock), or use_sim_time true with inputs stamped in wall time. Then
// every latency figure is meaningless, and the user is told once what to set.
#pragma once

#include <string>

namespace deep_ois {

// Stamps further than this from the clock disagree with it, seconds. Far above any latency the
// live pipeline lets through (frames wait for their IMU samples for well under a second), far
// below what a clock mix-up gives (hours to decades).
constexpr double kStampClockMaxOffsetS = 60.0;
// ROS time this far behind its previous reading went back (a bag that loops under use_sim_time, a
// restarted simulator), seconds: the check starts over and may say it again on the new timeline.
constexpr double kStampClockJumpBackS = 1.0;

class StampClockCheck {
 public:
  explicit StampClockCheck(double max_offset_s = kStampClockMaxOffsetS);

  // One input stamp read when the clock said `now_s` (seconds since the epoch of each). A clock
  // at zero (simulated time before its first /clock message) decides nothing. Returns true once
  // per timeline: for the first stamp far from the clock since the start or since ROS time went
  // back.
  bool observe(double stamp_s, double now_s);

  // Whether the latest stamp observed was far from the clock; `offsetS` is its stamp minus the
  // clock, seconds (negative: stamps in the clock's past).
  bool disagrees() const { return disagrees_; }
  double offsetS() const { return offset_s_; }

  // What the disagreement means and what to set, for a log line or /diagnostics (empty while the
  // stamps agree): the offset in readable units, the likely cause, and `use_sim_time` by name.
  std::string describe() const;

 private:
  double max_offset_s_;
  bool disagrees_ = false;
  bool said_ = false;  // on this timeline
  double offset_s_ = 0.0;
  double last_now_s_ = 0.0;
  bool seen_ = false;
};

// A duration in the unit a person reads it in: "42.0 s", "3.5 h", "12.0 days", "56.9 years".
std::string readableDuration(double seconds);

}  // namespace deep_ois
