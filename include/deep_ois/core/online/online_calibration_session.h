// One camera's online camera-IMU calibration as the compensation nodelet runs it on the learner's
// tracking thread (its on_tracked_pair hook), without ROS, so that the nodelet
// (ros/live/online_calibration_ros.h) and benchmark_online_learning --online-calibration run the
// same code: each tracked pair loses the lens motion the stabiliser model in use predicted for it
// (the shifts the compensation used; none while it fell back to the plain gyro), goes through
// DelayedCalibrationFeed into the OnlineCalibrationEstimator, and a calibration the estimator
// offers is put on trial (ConfirmedState): each later pair is scored with it, with the one it
// replaced and with the session's start, until it is confirmed (persisted) or undone; an undo also
// rewinds the estimator to its state before the undone swap (rewindBeforeSwap).
//
// Not thread-safe: one caller (the tracking thread, a replay) owns it. Pure Eigen + OpenCV: no ROS.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/online/confirmed_state.h"
#include "deep_ois/core/online/online_calibration_delayed_feed.h"
#include "deep_ois/core/online/online_calibration_estimator.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"

namespace deep_ois {

// The lens shifts the compensation used for one pair (frame b's stamp identifies it).
struct PairLensShift {
  double stamp_b_s = 0.0;
  std::vector<Eigen::Vector2d> shift_a_px, shift_b_px;  // per row patch, undistorted pixels
};

// The pair's tracks without `lens` (the shift moves undistorted pixels: K(s) = K with the principal
// point moved by s; each track takes the shift at its row, interpolated between the patches'
// capture rows).
std::vector<FeatureMatch> removeLensShift(const OnlineFramePair& pair, const PairLensShift& lens);

// The estimator's copy of a pair: no frames; the tracks without `lens` (null: the plain gyro was
// published, no lens to remove).
OnlineFramePair lenslessPair(const OnlineFramePair& pair, const PairLensShift* lens);

class OnlineCalibrationSession {
 public:
  // `options`: the estimator's; `confirm_pairs`: usable pairs a trial is scored on before it is
  // confirmed (the learner's ~learning_confirm_pairs); `persist` writes a confirmed calibration
  // (throws on failure), to `persisted_to` (a path, for the verdict's sentence). Throws
  // std::invalid_argument as the estimator does.
  OnlineCalibrationSession(const OnlineCalibrationOptions& options, std::size_t confirm_pairs,
                           const CameraModel& camera, const CameraImuCalibration& start,
                           ConfirmedState<CameraImuCalibration>::Persist persist, std::string persisted_to);

  // What one pair changed, for the log and the status.
  struct Outcome {
    std::string log;           // a sentence when a calibration was applied, undone or its trial ended
    std::string confirmation;  // the trial's progress or the last verdict ("" until there is one)
  };
  // One pair as the tracking thread got it (lensless: lenslessPair's copy).
  Outcome addPair(const OnlineFramePair& lensless);
  // Time went back: the buffered pairs belong to the other timeline.
  void restartTimeline();

  const OnlineCalibrationStatus& status() const { return estimator_.status(); }
  const CameraImuCalibration& inUse() const { return trials_.inUse(); }
  std::uint32_t appliedVersion() const { return applied_version_; }
  std::size_t swapsUndone() const { return swaps_undone_; }
  std::size_t swapsConfirmed() const { return swaps_confirmed_; }
  std::size_t savesFailed() const { return saves_failed_; }
  // Pairs the feed never gave the estimator (DelayedCalibrationFeed::dropped), and the repeats
  // among them.
  std::size_t pairsDropped() const { return feed_.dropped(); }
  std::size_t pairsRepeated() const { return feed_.repeats(); }

 private:
  // One pair the estimator has (its gyro covers it), scored for the calibration on trial.
  void judgeTrial(const OnlineCalibrationPair& pair);

  OnlineCalibrationEstimator estimator_;
  DelayedCalibrationFeed feed_;
  ConfirmedState<CameraImuCalibration> trials_;
  std::size_t confirm_pairs_;
  std::string persisted_to_;
  CameraImuCalibration session_start_;
  std::string confirmation_;  // the last trial's verdict
  std::uint64_t estimator_version_ = 0;
  std::uint64_t trial_first_version_ = 0;  // the estimator's version the trial's first swap made
  std::uint32_t applied_version_ = 0;
  std::size_t swaps_undone_ = 0, swaps_confirmed_ = 0, saves_failed_ = 0;
};

}  // namespace deep_ois
