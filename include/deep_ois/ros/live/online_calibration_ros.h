// The compensation nodelet's online camera-IMU calibration (core/online/online_calibration_estimator.h)
// in ROS terms; what runs on the tracking thread is core/online/online_calibration_session.h (shared
// with benchmark_online_learning --online-calibration). The online learner's tracking thread hands it every pair it tracked (its
// on_tracked_pair hook: no second tracker; DelayedCalibrationFeed holds each pair until the gyro of
// later pairs covers it, and the estimator's fits are charged to the learning's
// CPU budget besides the estimator's own); the tracks first lose the lens motion the stabiliser
// model in use predicted for the pair (the shifts the compensation published, or none while it
// falls back to the plain gyro), so the estimator fits a fixed-lens camera and the time offset
// cannot absorb the lens motion (nor the lens the timing: the model is fitted by the learner).
//
// A new calibration the estimator offers (confidently better on pairs it was not fitted on, by the
// model swap's margins) is applied at once and put on trial (confirmed_state.h): each later pair's
// tracks are scored with it, with the calibration it replaced and with the session's start; after
// ~learning_confirm_pairs usable pairs it is confirmed and written, atomically, to
// `<learned model file without .yaml>.calibration.yaml` (the gyro flow's parameter format, so it
// can also be given as calibration:=), or undone (the replaced calibration is applied again) when
// worse than what it replaced. The file is loaded at the next start as the calibration in use.
//
// "Applied" means published on `online_calibration` (OnlineCalibration, latched) with a new version;
// the gyro flow nodelet follows it (~follow_online_calibration) through its own dynamic_reconfigure
// server, so `dynparam get` shows the values in use and both nodelets' outputs use them.
//
// Threads: onTrackedPair runs on the learner's tracking thread and owns the estimator; the ROS
// side (rememberLens, afterPair, diagnostics) only reads a snapshot under a short lock: a callback
// never waits for a fit.
#pragma once

#include <deep_ois/GyroFlow.h>
#include <deep_ois/OnlineCalibration.h>
#include <ros/ros.h>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "deep_ois/core/online/online_calibration_session.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/ros/live/compensation_parameters.h"
#include "deep_ois/ros/live/live_diagnostics.h"
#include "deep_ois/ros/live/stabiliser_flow_compensator.h"

namespace deep_ois {

// The calibration file kept beside a learned model file (`x.yaml` -> `x.calibration.yaml`).
std::string onlineCalibrationPath(const std::string& learned_model_path);
// Reads a calibration file in the gyro flow's parameter format (time_offset, readout_time,
// imu_to_camera_rotation, gyro_bias); throws std::runtime_error naming the file and the field.
CameraImuCalibration loadCalibrationParameters(const std::string& path);
// The text written for a confirmed calibration (the same keys; sigmas as comments).
std::string onlineCalibrationYaml(const CameraImuCalibration& calibration, const std::string& note);

class OnlineCalibrationRos {
 public:
  OnlineCalibrationRos(ros::NodeHandle nh, const CompensationParameters& params, LiveDiagnostics& diagnostics,
                       const std::string& log_name);

  // The camera is known (its first pair, or another camera): `calibration_path` is where its
  // calibration is kept; the start is that file when it exists, else the gyro flow's values
  // (the message's offset, readout and rotation; the bias from ~online_calibration_gyro_flow's
  // gyro_bias parameter, else 0). ROS thread; the tracking thread makes the estimator at its next pair.
  // `lens_moves`: the model in use at the start predicts lens motion (an OIS camera, or one not
  // known to have none): the estimator then also fits a lens shift per frame
  // (LensShiftHandling::kPerFrameShift), as `calibrate --ois on`, so that the part of the lens
  // motion the model gets wrong (the shipped generic model on a new camera) is not absorbed by the
  // time offset; else the tracks are those of a fixed lens (kNone: tighter).
  void startFor(const std::string& calibration_path, const GyroFlow& gyro, bool lens_moves);
  // ROS thread, per compensated pair: the lens shifts the model predicted (none when falling back).
  void rememberLens(const GyroFlow& gyro, const StabiliserFlowResult& result, bool falling_back);
  // Tracking thread (OnlineLearningOptions::on_tracked_pair). Never throws.
  void onTrackedPair(const OnlineFramePair& pair);
  // ROS thread, per pair: publishes online_calibration when something changed, /diagnostics.
  void afterPair(const GyroFlow& gyro);
  void timeWentBack() { time_went_back_ = true; }

 private:
  // What the ROS thread shows; written by the tracking thread under snapshot_mutex_.
  struct Snapshot {
    bool started = false;
    OnlineCalibrationStatus status;
    CameraImuCalibration applied;  // in use (trials_->inUse())
    std::uint32_t applied_version = 0;
    std::string confirmation = "start";
    std::size_t swaps_undone = 0, swaps_confirmed = 0, saves_failed = 0;
    std::size_t pairs_dropped = 0;  // never reached the estimator: repeats, or waiting when time went back
    std::size_t pairs_repeated = 0;  // of which: repeats
    std::uint64_t changes = 0;  // +1 per change worth publishing
    std::string last_log;       // a sentence for the log, said once
    std::uint64_t log_id = 0;
  };
  // Tracking thread: the estimator's copy of the pair, without the lens motion the compensation used.
  OnlineFramePair withoutLens(const OnlineFramePair& pair) const;
  void work(const OnlineFramePair& pair);
  void publish(const GyroFlow& gyro, const Snapshot& snapshot);
  void updateDiagnostics(const Snapshot& snapshot, const GyroFlow& gyro);

  ros::NodeHandle nh_;
  CompensationParameters params_;
  LiveDiagnostics& diagnostics_;
  std::string log_name_;
  ros::Publisher pub_;

  // Set by startFor (ROS thread) before the tracking thread reads them (under snapshot_mutex_).
  std::string path_;
  CameraImuCalibration start_;
  std::string start_source_;
  bool lens_moves_ = true;
  std::uint64_t camera_generation_ = 0;

  mutable std::mutex snapshot_mutex_;  // snapshot_, lenses_, path_, start_, camera_generation_
  Snapshot snapshot_;
  std::deque<PairLensShift> lenses_;
  std::atomic<bool> time_went_back_{false};

  // Tracking thread only.
  std::uint64_t estimator_generation_ = 0;
  std::unique_ptr<OnlineCalibrationSession> session_;

  // ROS thread only.
  std::uint64_t published_changes_ = ~std::uint64_t{0};
  std::uint64_t logged_id_ = 0;
  std::size_t pairs_ = 0;
};

}  // namespace deep_ois
