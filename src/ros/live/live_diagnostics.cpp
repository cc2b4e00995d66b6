#include "deep_ois/ros/live/live_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "deep_ois/core/common/printf_text.h"
#include "deep_ois/ros/live/parameter_source.h"

namespace deep_ois {

double loadDiagnosticPeriodS(const ParameterSource& source) {
  const double period_s = source.param("diagnostic_period", 1.0);
  if (!(period_s > 0.0) || !std::isfinite(period_s)) {
    throw std::invalid_argument("parameter " + source.describe("diagnostic_period") +
                                ": must be a positive number of seconds, got " + std::to_string(period_s));
  }
  return period_s;
}

LiveDiagnostics::LiveDiagnostics(const ros::NodeHandle& nh, const ros::NodeHandle& private_nh,
                                 const std::vector<std::string>& streams, const std::string& output_stream,
                                 const std::string& hardware_id)
    : streams_(streams),
      output_stream_(output_stream),
      window_start_(ros::WallTime::now()),
      updater_(nh, private_nh, private_nh.getNamespace()) {
  for (const std::string& stream : streams_) window_ticks_[stream] = total_ticks_[stream] = 0;
  updater_.setHardwareID(hardware_id);
  updater_.add("status", this, &LiveDiagnostics::report);
  // Read with the nodelets' strict parameter source: a wrong type or value is an error naming it.
  period_s_ = loadDiagnosticPeriodS(NodeHandleParameters(private_nh));
  timer_ = private_nh.createWallTimer(ros::WallDuration(period_s_), &LiveDiagnostics::timerCallback, this);
}

LiveDiagnostics::~LiveDiagnostics() { timer_.stop(); }

void LiveDiagnostics::tick(const std::string& stream) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_ticks_[stream];
  ++total_ticks_[stream];
}

void LiveDiagnostics::drop(const std::string& reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++drops_total_[reason];
  ++drops_in_window_;
}

void LiveDiagnostics::latency(double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  latency_sum_s_ += seconds;
  latency_max_s_ = std::max(latency_max_s_, seconds);
  ++latency_count_;
}

void LiveDiagnostics::setValue(const std::string& key, const std::string& value) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& entry : values_) {
    if (entry.first == key) {
      entry.second = value;
      return;
    }
  }
  values_.emplace_back(key, value);
}

void LiveDiagnostics::setClockProblem(const std::string& problem) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (problem != clock_problem_) clock_problem_ = problem;
}

void LiveDiagnostics::timerCallback(const ros::WallTimerEvent&) { updater_.force_update(); }

void LiveDiagnostics::report(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double window_s = std::max(1e-6, (now - window_start_).toSec());
  bool inputs_flow = false;
  for (const std::string& stream : streams_) {
    status.add(stream + " rate [Hz]", printfText("%.2f", window_ticks_[stream] / window_s));
    status.add(stream + " total", total_ticks_[stream]);
    if (stream != output_stream_ && window_ticks_[stream] > 0) inputs_flow = true;
  }
  std::size_t drops_total = 0;
  for (const auto& [reason, count] : drops_total_) {
    status.add("dropped: " + reason, count);
    drops_total += count;
  }
  status.add("dropped total", drops_total);
  status.add("dropped in last period", drops_in_window_);
  if (!clock_problem_.empty()) {
    // Stamp minus clock of two clocks: not a latency.
    status.add("latency mean [s]", "not measurable: " + clock_problem_);
    status.add("latency max [s]", "not measurable (see latency mean)");
  } else {
    status.add("latency mean [s]", printfText("%.4f", latency_count_ > 0 ? latency_sum_s_ / latency_count_ : 0.0));
    status.add("latency max [s]", printfText("%.4f", latency_max_s_));
  }
  for (const auto& [key, value] : values_) status.add(key, value);

  const std::size_t outputs = window_ticks_[output_stream_];
  if (!clock_problem_.empty()) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "input stamps and ROS time disagree (use_sim_time?): see latency mean");
  } else if (drops_in_window_ > 0) {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%zu dropped in the last %.1f s (%zu in all)",
                    drops_in_window_, window_s, drops_total);
  } else if (inputs_flow && outputs == 0) {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "inputs arrive but no %s in the last %.1f s",
                    output_stream_.c_str(), window_s);
  } else {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::OK, "%.1f %s/s", outputs / window_s,
                    output_stream_.c_str());
  }

  for (auto& [stream, count] : window_ticks_) count = 0;
  drops_in_window_ = 0;
  latency_sum_s_ = latency_max_s_ = 0.0;
  latency_count_ = 0;
  window_start_ = now;
}

}  // namespace deep_ois
