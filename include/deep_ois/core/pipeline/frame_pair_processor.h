// The motion of one frame pair a -> b of an OIS camera, computed the one way every part of the
// package computes it: the live nodelets, `evaluate` and the benchmarks all call this class, so a
// new step of the recipe (e.g. fusing the motion with image tracks) is added here, once.
//
// The recipe, per pair (it was typed out in five places before: GyroFlowRos::processFrame,
// benchmark_compensation, benchmark_online_learning, the stabiliser's table row and the
// compensation nodelet's StabiliserFlowCompensator):
//   1. The gyro's motion: per row patch, the rotation R_b_a integrated from the IMU buffer and
//      K R K^-1 (core/gyro/rolling_shutter_homographies.h). gyroMotion() below; skipped when the
//      pair already carries it (a GyroFlow message, the evaluator's pair context).
//   2. The lens: K(s_b) R K(s_a)^-1 per patch (core/ois/lens_shift_homographies.h), with the
//      lens shift s from
//        - the camera's lens log, when the pair has one and it covers the pair (a measurement
//          beats a prediction); a log that does not cover the pair falls back to the gyro alone,
//          and the result says why;
//        - else the stabiliser model (core/ois/stabiliser_compensator.h), when the processor has
//          one. The model is one state per camera stream: it is fed the pair's gyro stream (only
//          samples newer than it has; a fresh model is first run over kStabiliserWarmUpS of
//          history, the warm-up), restarted from a centred lens when time goes back (a bag that
//          loops) and carried across an applied calibration. A pair with the lens log still feeds
//          the model, so it stays warm for the next pair without the log;
//        - else nothing: the gyro's K R K^-1 (a camera without OIS, or the gyro flow nodelet).
//   3. The fusion, when the pair carries tracks and fusion options: the motion of step 2 is the
//      prior, refined by the tracks where they support it (core/fusion/fused_motion.h). A fusion
//      that throws keeps the prior and says why (FramePairMotion::fusion_failed): never an error
//      of the pair.
//   4. The render: the homographies as the dense CV_32FC2 flow on the working grid
//      (core/flow/homography_flow.h), when a grid is asked for.
// The pair's gyro stream, from the warm-up before frame a's first patch to frame b's last patch,
// is pairGyroStream(): what every GyroFlow message carries and the online learner is handed.
//
// What differs between the callers (they build a FramePair and read a FramePairMotion):
//   - GyroFlowRos (live gyro flow nodelet): IMU buffer in, lens log in (~use_lens_shift_log), no
//     model; runs gyroMotion() itself first (it waits for IMU data and for the lens log between
//     the steps); out: the homographies, the flow on ~grid, the motion model for the message.
//   - StabiliserFlowCompensator (compensation nodelet, ros/live/): a GyroFlow message in, whose
//     homographies give the rotations and whose gyro stream (`rates`) feeds the model; the
//     message's calibration epoch gives the calibration shift; out: the model's homographies,
//     lens shifts and the flow on the message's grid. The fallback to the plain gyro, decided by
//     the online learner's per-pair check after it has seen the model's motion, stays with
//     CompensationRos.
//   - the stabiliser's table row (`evaluate`, core/evaluation/): the evaluator's pair context in
//     (rotations given, the recording's IMU buffer); one processor per recording; pairs in
//     recording order, not a live stream, so the timeline is not followed (kPairsInOrder); out:
//     the homographies, no render.
//   - benchmark_online_learning: as the table row but as the live nodelet (timeline followed,
//     model swapped when the learner swaps it, fallback read from the learner); out: the
//     homographies and the pair's gyro stream for the learner.
//   - benchmark_compensation: a synthetic IMU buffer; the gyro flow nodelet's half (steps 1 and
//     3) and the compensation nodelet's (through StabiliserFlowCompensator), timed per stage.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/fusion/fused_motion.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

// The span of gyro stream a pair's motion needs (IMU clock, seconds): from the stabiliser model's
// warm-up before frame a's first patch to frame b's last patch.
struct PairGyroSpan {
  double from_s = 0.0;
  double until_s = 0.0;
};
PairGyroSpan pairGyroSpan(const RollingShutterConfig& timing, double stamp_a_s, double stamp_b_s);

// The camera-frame gyro rates over pairGyroSpan() (cameraRates(): the samples after from_s up to
// the first at or after until_s). Frame stamps on the camera clock, rates on the IMU clock.
std::vector<CameraRateSample> pairGyroStream(const ImuSampleBuffer& imu, const RollingShutterConfig& timing,
                                             double stamp_a_s, double stamp_b_s);

// One frame pair, as the caller has it. Pointers are not owned and must outlive the call.
struct FramePair {
  double stamp_a_s = 0.0, stamp_b_s = 0.0;  // frame stamps, camera clock (the IMU buffer's time base)
  RollingShutterConfig timing;              // patches, readout, time offset, IMU -> camera rotation
  const CameraModel* camera = nullptr;      // K (and distortion and size, for the render)
  // The gyro's motion per patch: R_b_a and K R K^-1. Filled by gyroMotion() when empty.
  std::vector<Eigen::Matrix3d> rotations, gyro_homographies;
  // The gyro stream: an IMU buffer, or the camera-frame rates the pair carries (a GyroFlow
  // message's, pairGyroStream(); overlapping earlier pairs is fine). Either is enough for the
  // model; the buffer (with `integration`) also gives the gyro's motion when it is not given.
  const ImuSampleBuffer* imu = nullptr;
  const std::vector<CameraRateSample>* rates = nullptr;
  IntegrationOptions integration;
  // The camera's lens log (camera clock, its convention applied), used when it covers the pair.
  const LensShiftLog* lens_log = nullptr;
  // How far a calibration applied since the previous pair moved the IMU times of the frames (new
  // time offset minus old, seconds; StabiliserCompensator::followTimeline). 0 when unchanged.
  double calibration_shift_s = 0.0;
  // Step 3, the fusion, when both are set: `tracks` on raw pixels of `camera`, frame a -> b, and
  // the prior's 1-sigma transfer error (MotionPrior::sigma_px), pixels.
  const FusionOptions* fusion = nullptr;
  const std::vector<FeatureMatch>* tracks = nullptr;
  double prior_sigma_px = MotionPrior().sigma_px;
};

// Where a pair's motion came from.
enum class PairMotionSource {
  kGyro,             // K R K^-1: no lens (no model, or a lens log that did not cover the pair)
  kLensLog,          // K(s_b) R K(s_a)^-1 with the logged lens shift
  kStabiliserModel,  // K(s_b) R K(s_a)^-1 with the stabiliser model's lens shift
};

struct FramePairMotion {
  bool ok = false;
  // Not ok: why there is no motion (the IMU or the model's gyro stream does not cover the pair).
  // Ok from the gyro while a lens log was given: why the log was not used.
  std::string reason;
  IntegrationStatus gyro_status = IntegrationStatus::kOk;  // step 1's, when it ran and failed
  PairMotionSource source = PairMotionSource::kGyro;
  std::vector<Eigen::Matrix3d> rotations;          // the gyro's R_b_a per patch
  std::vector<Eigen::Matrix3d> gyro_homographies;  // K R K^-1 per patch, undistorted pixels
  std::vector<Eigen::Matrix3d> homographies;       // the pair's motion per patch, undistorted pixels
  // The stabiliser model's lens shifts at the patch times (pixels), with kStabiliserModel only.
  std::vector<Eigen::Vector2d> shift_a_px, shift_b_px;
  // Seconds time went back before this pair (the model restarted from a centred lens); 0 if not.
  double time_jump_back_s = 0.0;
  cv::Mat flow;  // CV_32FC2 on the grid asked for; empty when none was
  // With the fusion: its result (`homographies` are its homographies, the prior's when not
  // refined) and step 2's motion, the prior (what the per-pair check scores).
  std::optional<FusedMotion> fused;
  std::vector<Eigen::Matrix3d> prior_homographies;
  bool fusion_failed = false;  // fuseMotion threw: the prior is kept, fused->reason says why
};

class FramePairProcessor {
 public:
  // Whether the model follows the stream's timeline (StabiliserCompensator::followTimeline):
  // kRestartWhenTimeGoesBack for a live stream (a bag that loops, a restarted replay), or
  // kPairsInOrder for the evaluator, whose pairs come in recording order from one recording.
  enum class Timeline { kRestartWhenTimeGoesBack, kPairsInOrder };

  // Without a stabiliser model: the gyro, or the lens log where it covers the pair.
  FramePairProcessor() = default;
  // With a stabiliser model (throws std::invalid_argument for invalid parameters at the first
  // pair, as StabiliserCompensator).
  explicit FramePairProcessor(const StabiliserModel& model,
                              Timeline timeline = Timeline::kRestartWhenTimeGoesBack);

  // Step 1 alone: the gyro's per-patch rotations and homographies from `pair.imu`.
  static RollingShutterHomographies gyroMotion(const FramePair& pair);

  // The pair's motion (steps 1 to 4), rendered on `grid` unless it is empty. Not ok, with the
  // reason, when the gyro or the model's gyro stream does not cover the pair. Throws
  // std::invalid_argument for a pair without a camera or without a gyro (no rotations, no IMU).
  FramePairMotion process(FramePair pair, cv::Size grid = cv::Size());
  // Feeds the pair's gyro stream to the model without a motion (a pair without an output still
  // moved the lens). Returns how far time went back before it (seconds; 0 when it did not).
  double observe(const FramePair& pair);

  // Step 3 alone: `homographies` as a CV_32FC2 flow on `grid` (the renderer is kept per camera,
  // grid and patch count).
  void render(const CameraModel& camera, cv::Size grid, const std::vector<Eigen::Matrix3d>& homographies,
              cv::Mat& flow);

  bool hasModel() const { return model_.has_value(); }
  // Another model (the online learner's swap): the stabiliser restarts from a centred lens at the
  // next pair, warmed up on the gyro history it carries.
  void setModel(const StabiliserModel& model);
  // Forgets the model's state (another recording): as a fresh processor with the same model.
  void restart() { compensator_.reset(); }

  int stateResets() const { return compensator_ ? compensator_->stateResets() : 0; }
  int timeJumps() const { return compensator_ ? compensator_->timeJumps() : 0; }
  int calibrationChanges() const { return compensator_ ? compensator_->calibrationChanges() : 0; }
  int calibrationRestarts() const { return compensator_ ? compensator_->calibrationRestarts() : 0; }

 private:
  // The model's state for the pair's camera (rebuilt when K changes), its timeline followed and
  // fed with the pair's gyro stream up to frame b's last patch.
  StabiliserCompensator& feedModel(const FramePair& pair, double* time_jump_back_s);
  // Step 3: motion.homographies become the fused ones; the prior is kept in prior_homographies.
  static void fuse(const FramePair& pair, FramePairMotion& motion);

  std::optional<StabiliserModel> model_;
  Timeline timeline_ = Timeline::kRestartWhenTimeGoesBack;
  std::unique_ptr<StabiliserCompensator> compensator_;
  Eigen::Matrix3d K_ = Eigen::Matrix3d::Zero();  // the camera compensator_ was built for
  std::unique_ptr<HomographyFlowRenderer> renderer_;
};

}  // namespace deep_ois
