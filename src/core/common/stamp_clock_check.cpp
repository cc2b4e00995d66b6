#include "deep_ois/core/common/stamp_clock_check.h"

#include <cmath>
#include <cstdio>

namespace deep_ois {

StampClockCheck::StampClockCheck(double max_offset_s) : max_offset_s_(max_offset_s) {}

bool StampClockCheck::observe(double stamp_s, double now_s) {
  if (!(now_s > 0.0) || !std::isfinite(stamp_s) || !std::isfinite(now_s)) return false;
  // ROS time went back (a bag looping under use_sim_time, a restarted simulator): a new timeline,
  // with its own verdict. Stamps alone going back do not re-arm it: messages of two inputs cross
  // (an IMU sample stamped after the clock changed, a frame before), and a bag looping while
  // use_sim_time is false is the same mistake, already said.
  if (seen_ && now_s < last_now_s_ - kStampClockJumpBackS) said_ = false;
  seen_ = true;
  last_now_s_ = now_s;
  offset_s_ = stamp_s - now_s;
  disagrees_ = std::abs(offset_s_) > max_offset_s_;
  if (!disagrees_ || said_) return false;
  said_ = true;
  return true;
}

std::string StampClockCheck::describe() const {
  if (!disagrees_) return {};
  const std::string offset = readableDuration(std::abs(offset_s_));
  if (offset_s_ < 0.0) {
    return "input stamps are " + offset +
           " behind ROS time: stamps of a recording read on the wall clock, as when `rosbag play "
           "--clock` runs while use_sim_time is false (set it true: use_sim_time:=true with "
           "deep_ois.launch, or `rosparam set use_sim_time true` before the nodes start); latency "
           "figures mean nothing until then";
  }
  return "input stamps are " + offset +
         " ahead of ROS time: use_sim_time is true (a /clock from a bag or simulator) but the inputs "
         "are stamped on another clock, e.g. a live driver's wall time (set use_sim_time false for "
         "live sensors, use_sim_time:=false with deep_ois.launch); latency figures mean nothing "
         "until then";
}

std::string readableDuration(double seconds) {
  char text[64];
  const double s = std::abs(seconds);
  if (s < 120.0) {
    std::snprintf(text, sizeof text, "%.1f s", seconds);
  } else if (s < 2.0 * 3600.0) {
    std::snprintf(text, sizeof text, "%.1f min", seconds / 60.0);
  } else if (s < 2.0 * 86400.0) {
    std::snprintf(text, sizeof text, "%.1f h", seconds / 3600.0);
  } else if (s < 2.0 * 365.25 * 86400.0) {
    std::snprintf(text, sizeof text, "%.1f days", seconds / 86400.0);
  } else {
    std::snprintf(text, sizeof text, "%.1f years", seconds / (365.25 * 86400.0));
  }
  return text;
}

}  // namespace deep_ois
