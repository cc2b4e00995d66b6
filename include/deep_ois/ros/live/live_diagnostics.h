// /diagnostics of a live nodelet through diagnostic_updater: message rates of its inputs and
// outputs, dropped frame pairs (counted per reason), latency, and the configuration in use (model,
// calibration). One status per nodelet, named after its private namespace, so that two cameras in
// one manager are told apart.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/node_handle.h>
#include <ros/wall_timer.h>

#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "deep_ois/ros/live/parameter_source.h"

namespace deep_ois {

// Every method is thread-safe (one internal mutex) and cheap enough to call from a callback while
// the wrapper holds its own lock: nothing here calls back into the wrapper.
//
// The status is published every ~diagnostic_period seconds of wall time (default 1; wall time, so
// that a paused bag replay still reports). Its level is WARN while frame pairs were dropped in the
// last period or while inputs arrive but no output is produced, OK otherwise.
// ~diagnostic_period (seconds, default 1); throws std::invalid_argument naming it when not > 0.
double loadDiagnosticPeriodS(const ParameterSource& source);

class LiveDiagnostics {
 public:
  // `streams`: the names of the message streams whose rates are reported (e.g. "imu", "frames",
  // "gyro flows"), in that order; `output_stream` is the one whose silence while the inputs flow
  // is a warning. `hardware_id`: what the nodelet serves (e.g. its camera topic).
  LiveDiagnostics(const ros::NodeHandle& nh, const ros::NodeHandle& private_nh,
                  const std::vector<std::string>& streams, const std::string& output_stream,
                  const std::string& hardware_id);
  ~LiveDiagnostics();

  LiveDiagnostics(const LiveDiagnostics&) = delete;
  LiveDiagnostics& operator=(const LiveDiagnostics&) = delete;

  // One message on `stream` (one of the streams named at construction).
  void tick(const std::string& stream);
  // One frame pair (or frame) dropped or skipped, with a short reason ("IMU gap", ...).
  void drop(const std::string& reason);
  // Seconds from an output's stamp (its frame's capture) to its publication.
  void latency(double seconds);
  // A configuration value shown with the status (model, time offset, ...).
  void setValue(const std::string& key, const std::string& value);
  // The input stamps disagree with ROS time (StampClockCheck::describe(); empty: they agree).
  // While set, the latency figures are replaced by this text and the status is a warning.
  void setClockProblem(const std::string& problem);
  // Seconds between two statuses (~diagnostic_period).
  double periodS() const { return period_s_; }

 private:
  void report(diagnostic_updater::DiagnosticStatusWrapper& status);
  void timerCallback(const ros::WallTimerEvent&);

  std::mutex mutex_;
  double period_s_ = 1.0;
  std::vector<std::string> streams_;
  std::string output_stream_;
  std::map<std::string, std::size_t> window_ticks_, total_ticks_;
  std::map<std::string, std::size_t> drops_total_;
  std::size_t drops_in_window_ = 0;
  double latency_sum_s_ = 0.0, latency_max_s_ = 0.0;
  std::size_t latency_count_ = 0;
  std::vector<std::pair<std::string, std::string>> values_;  // in the order first set
  std::string clock_problem_;
  ros::WallTime window_start_;

  diagnostic_updater::Updater updater_;
  ros::WallTimer timer_;
};

}  // namespace deep_ois
