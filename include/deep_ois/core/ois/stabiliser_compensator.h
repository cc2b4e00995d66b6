// OIS compensation from the gyro stream with a learned stabiliser model: the compensated motion of
// a frame pair is K(s_b) R K(s_a)^-1 per row patch (core/ois/lens_shift_homographies.h), with the
// gyro's rotations R and the lens shifts s the model predicts at the patches' capture times.
//
// One per camera stream: it carries the stabiliser's state from pair to pair. The compensation
// nodelet, the evaluator and the benchmark all go through it (the same computation live and
// offline). A gap in the gyro stream restarts the model from a centred lens (counted), and so
// does time going back (a bag that loops, a replay restarted: followTimeline).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

// Seconds of gyro history a stabiliser model is run over before the first pair of a stream (the
// lens state depends on it; a few centring time constants). The gyro flow nodelet sends this much
// with every GyroFlow message, so the live chain starts from the same history as the evaluator.
constexpr double kStabiliserWarmUpS = 1.0;

// The camera-frame rates of the IMU samples after after_s up to and including the first at or
// after until_s (IMU clock, seconds): what a model needs to answer at until_s.
std::vector<CameraRateSample> cameraRates(const ImuSampleBuffer& imu,
                                          const Eigen::Matrix3d& imu_to_camera_rotation,
                                          double after_s, double until_s);

struct StabiliserCompensation {
  bool ok = false;
  std::string reason;  // why not, when !ok
  std::vector<Eigen::Vector2d> shift_a_px, shift_b_px;  // per patch, at the patch times
  std::vector<Eigen::Matrix3d> homographies;             // K(s_b) R K(s_a)^-1, undistorted pixels
};

class StabiliserCompensator {
 public:
  // Throws std::invalid_argument for invalid parameters or a non-positive focal length.
  // `warm_up_s`: at the start of a stream (or after a gap) the model is first run over this much
  // of the gyro history before the pair, when the caller has it (the lens state depends on it).
  StabiliserCompensator(const StabiliserModel& parameters, const Eigen::Matrix3d& K,
                        double warm_up_s = kStabiliserWarmUpS);

  // Call before feeding a pair's rates, with the times of the same patch (e.g. the first) of the
  // pair's frames a and b (IMU clock, seconds). Time is not monotonic: a pair whose frame a is
  // older than the last pair's frame b belongs to another timeline (a bag that loops, a replay
  // restarted, a clock reset), so the model restarts from a centred lens and is warmed up again
  // from the gyro history fed next; nothing of the other timeline's state is used. Returns how far
  // time went back (seconds), 0 when it did not.
  //
  // `calibration_shift_s`: how far a calibration applied since the last pair moved the IMU times
  // of the camera's frames (the new time offset minus the old, seconds; 0 when the calibration did
  // not change). An applied calibration is not a time jump: the gyro stream (IMU clock) goes on,
  // only the times the model is asked about move, so the state is carried across it (counted in
  // calibrationChanges()); only a move back beyond the shift is another timeline. A shift back
  // further than the model's retained history cannot be answered: the model restarts then, as
  // after a gap (counted in calibrationRestarts(), not as a time jump).
  double followTimeline(double frame_a_s, double frame_b_s, double calibration_shift_s = 0.0);
  // Appends camera-frame rates in time order; older or repeated samples are ignored (consecutive
  // pairs carry overlapping gyro history).
  void addRates(const std::vector<CameraRateSample>& rates);
  // The IMU time from which the caller should feed rates before compensating a pair whose first
  // patch is at t_first_s: the model's newest sample, or t_first_s - warm_up_s for a fresh model.
  double feedFrom(double t_first_s) const;

  // The compensated motion of a pair from the gyro's per-patch rotations and the patch capture
  // times (IMU clock, seconds). Not ok when the model does not cover the times (the gyro stream
  // has not reached t_b, or started after t_a): the caller falls back and counts it.
  StabiliserCompensation compensate(const std::vector<Eigen::Matrix3d>& rotations,
                                    const std::vector<double>& patch_times_a_s,
                                    const std::vector<double>& patch_times_b_s) const;

  void reset() { predictor_.reset(); }
  int stateResets() const { return predictor_.resets(); }
  int timeJumps() const { return time_jumps_; }
  int calibrationChanges() const { return calibration_changes_; }
  int calibrationRestarts() const { return calibration_restarts_; }
  const LensShiftPredictor& predictor() const { return predictor_; }

 private:
  Eigen::Matrix3d K_;
  double warm_up_s_;
  LensShiftPredictor predictor_;
  bool seen_pair_ = false;
  double last_frame_b_s_ = 0.0;
  int time_jumps_ = 0;
  int calibration_changes_ = 0;   // applied calibrations the state was carried across
  int calibration_restarts_ = 0;  // of which: moved back beyond the retained history (restarted)
};

}  // namespace deep_ois
