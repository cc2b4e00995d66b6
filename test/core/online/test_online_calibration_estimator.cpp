// The online calibration on synthetic tracks from the simulator's geometry (no rendering): known
// offset, readout, bias and mount, a wrong start, drift, a jump, a still and a textureless camera.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <iostream>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/online/online_calibration_estimator.h"
#include "deep_ois/core/online/online_calibration_feed.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/sim/synthetic_track_recording.h"

namespace deep_ois {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// A hand-held camera (the simulator's defaults: 360x270, 22 ms readout) whose IMU is 23 ms late,
// with a bias and a mount a few degrees off an axis permutation.
sim::SimulatorConfig handHeldCamera(bool ois) {
  sim::SimulatorConfig config;
  config.ois.enabled = ois;
  config.imu.time_offset_s = 0.023;
  config.imu.gyro_initial_bias_vector_rad_s = Eigen::Vector3d(0.004, -0.003, 0.002);
  config.imu.gyro_bias_random_walk = 0.0;
  config.imu.imu_to_camera_rotation = expSO3(Eigen::Vector3d(1.5, -2.0, 1.0) * kDeg) * signedAxisPermutations()[13];
  return config;
}

// The wrong start of issue 33: offset off by 15 ms, readout off by 8 ms, bias unknown, the mount a
// wrong axis permutation.
CameraImuCalibration wrongStart(const sim::SyntheticTrackRecording& recording) {
  CameraImuCalibration start;
  start.time_offset_s = recording.time_offset_s(0.0) + 0.015;
  start.readout_time_s = recording.readout_time_s - 0.008;
  start.imu_to_camera_rotation = signedAxisPermutations()[0];
  EXPECT_NE(nearestSignedAxisPermutation(recording.imu_to_camera_rotation), 0);
  return start;
}

CameraImuCalibration truthAt(const sim::SyntheticTrackRecording& recording, double t) {
  CameraImuCalibration truth;
  truth.time_offset_s = recording.time_offset_s(t);
  truth.readout_time_s = recording.readout_time_s;
  truth.gyro_bias_rad_s = recording.mean_bias_rad_s;
  truth.imu_to_camera_rotation = recording.imu_to_camera_rotation;
  return truth;
}

// The estimator without its CPU budget: the fits then happen at the same pairs on every run (the
// budget's timing depends on the machine; StaysWithinItsCpuShare tests it).
OnlineCalibrationOptions unbudgeted() {
  OnlineCalibrationOptions options;
  options.cpu_share = 0.0;
  return options;
}

// Replays the recording in time order, the gyro 0.2 s ahead of the frames (as it arrives live);
// `after_pair(t)` runs after every pair (t: its frame b's stamp).
void replay(const sim::SyntheticTrackRecording& recording, OnlineCalibrationEstimator& estimator,
            const std::function<void(double)>& after_pair = {}, bool without_lens = false) {
  std::size_t next_gyro = 0;
  for (const sim::SyntheticTrackPair& pair : recording.pairs) {
    const double gyro_until_s = pair.stamp_b_s + recording.time_offset_s(pair.stamp_b_s) + 0.2;
    while (next_gyro < recording.gyro.size() && recording.gyro[next_gyro].stamp_s <= gyro_until_s) {
      estimator.addGyro(recording.gyro[next_gyro++]);
    }
    estimator.addPair({pair.stamp_a_s, pair.stamp_b_s, without_lens ? pair.matches_without_lens : pair.matches});
    while (estimator.update()) {
    }
    if (after_pair) after_pair(pair.stamp_b_s);
  }
}

void say(const std::string& label, const OnlineCalibrationStatus& status, const CameraImuCalibration& truth) {
  std::cout << "[ measured ] " << label << ": state " << status.state << ", in use offset error "
            << (status.in_use.time_offset_s - truth.time_offset_s) * 1e3 << " ms, readout error "
            << (status.in_use.readout_time_s - truth.readout_time_s) * 1e3 << " ms, bias error "
            << (status.in_use.gyro_bias_rad_s - truth.gyro_bias_rad_s).norm() << " rad/s, mount error "
            << rotationAngleBetween(status.in_use.imu_to_camera_rotation, truth.imu_to_camera_rotation) / kDeg
            << " deg; estimate offset error " << (status.estimate.time_offset_s - truth.time_offset_s) * 1e3
            << " +- " << status.estimate.time_offset_sigma_s * 1e3 << " ms, readout error "
            << (status.estimate.readout_time_s - truth.readout_time_s) * 1e3 << " +- "
            << status.estimate.readout_time_sigma_s * 1e3 << " ms, bias error "
            << (status.estimate.gyro_bias_rad_s - truth.gyro_bias_rad_s).transpose() << " (sigma "
            << status.estimate.gyro_bias_sigma_rad_s.transpose() << ") rad/s; " << status.fits << " fits ("
            << status.fits_rejected << " rejected, " << status.fits_needing_motion << " needing motion), "
            << status.swaps << " swaps (" << status.refinements << " refinements), " << status.jumps << " jumps, last fit " << status.last_fit_seconds
            << " s; " << status.last_reason << "\n";
}

TEST(OnlineCalibrationEstimator, ConvergesFromAWrongStartWithoutOis) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 30.0;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, wrongStart(recording));
  double converged_at_s = -1.0;
  const CameraImuCalibration truth = truthAt(recording, 0.0);
  replay(recording, estimator, [&](double t) {
    const CameraImuCalibration& in_use = estimator.status().in_use;
    // Issue 33's target is 0.5 ms / 1 ms after 30 s; the 3 s windows carry a bias of about -0.3 ms
    // on these tracks (within their 1-sigma), so the calibration in use may end a little beyond it.
    const bool close = std::abs(in_use.timeOffsetAt(t) - truth.time_offset_s) < 0.75e-3 &&
                       std::abs(in_use.readout_time_s - truth.readout_time_s) < 1e-3;
    if (close && converged_at_s < 0.0) converged_at_s = t;
    if (!close) converged_at_s = -1.0;
  });
  const OnlineCalibrationStatus& status = estimator.status();
  say("wrong start, OIS off, 30 s", status, truth);
  std::cout << "[ measured ] in use within 0.75 ms / 1 ms from " << converged_at_s << " s on\n";
  EXPECT_TRUE(status.mount_found);
  EXPECT_EQ(status.mount_permutation_index, nearestSignedAxisPermutation(truth.imu_to_camera_rotation));
  // The wrong start is a permutation 90 deg or more away; 3 s windows with hand translation pin the
  // small rotation to about a degree.
  EXPECT_LT(rotationAngleBetween(status.in_use.imu_to_camera_rotation, truth.imu_to_camera_rotation), 1.5 * kDeg);
  EXPECT_NEAR(status.in_use.time_offset_s, truth.time_offset_s, 0.75e-3);
  EXPECT_NEAR(status.in_use.readout_time_s, truth.readout_time_s, 1e-3);
  // The bias moves a track by bias x 33 ms x focal (1 mrad/s is 0.01 px, below the tracks' noise):
  // weakly determined, but its reported 1-sigma must cover it, and it must beat the unknown start.
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_LT(std::abs(status.estimate.gyro_bias_rad_s(axis) - truth.gyro_bias_rad_s(axis)),
              3.0 * status.estimate.gyro_bias_sigma_rad_s(axis) + 1e-4) << "axis " << axis;
  }
  EXPECT_LT((status.in_use.gyro_bias_rad_s - truth.gyro_bias_rad_s).norm(), 0.8 * truth.gyro_bias_rad_s.norm());
  // Within the targets well before 30 s, and the reported 1-sigma covers the error.
  EXPECT_GE(converged_at_s, 0.0);
  EXPECT_LT(converged_at_s, 20.0);
  EXPECT_LT(std::abs(status.estimate.time_offset_s - truth.time_offset_s), 3.0 * status.estimate.time_offset_sigma_s);
  EXPECT_GT(status.swaps, 0u);
}

TEST(OnlineCalibrationEstimator, ConvergesFromAWrongStartWithOis) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 30.0;
  options.seed = 2;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(true), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.lens_shift = LensShiftHandling::kPerFrameShift;
  OnlineCalibrationEstimator estimator(online, recording.camera, wrongStart(recording));
  replay(recording, estimator);
  const OnlineCalibrationStatus& status = estimator.status();
  const CameraImuCalibration truth = truthAt(recording, 0.0);
  say("wrong start, OIS on, 30 s", status, truth);
  EXPECT_EQ(status.mount_permutation_index, nearestSignedAxisPermutation(truth.imu_to_camera_rotation));
  EXPECT_NEAR(status.in_use.time_offset_s, truth.time_offset_s, 0.5e-3);
  EXPECT_NEAR(status.in_use.readout_time_s, truth.readout_time_s, 1e-3);
}

TEST(OnlineCalibrationEstimator, KeepsARightCalibration) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 15.0;
  options.seed = 3;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.estimate_rotation = false;
  const CameraImuCalibration truth = truthAt(recording, 0.0);
  OnlineCalibrationEstimator estimator(online, recording.camera, truth);
  replay(recording, estimator);
  const OnlineCalibrationStatus& status = estimator.status();
  say("right start, 15 s", status, truth);
  EXPECT_GT(status.candidates_scored, 3u);
  // A candidate as good as the calibration in use is not clearly better: nothing moves, or only
  // within what the tracks can tell.
  EXPECT_NEAR(status.in_use.time_offset_s, truth.time_offset_s, 0.3e-3);
  EXPECT_NEAR(status.in_use.readout_time_s, truth.readout_time_s, 0.5e-3);
}

TEST(OnlineCalibrationEstimator, TracksADriftingOffset) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 40.0;
  options.seed = 4;
  options.extra_offset_s = [](double t) { return 3e-3 * t / 60.0; };  // 3 ms a minute
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.estimate_rotation = false;
  online.apply_drift_rate = true;  // the default, said here: this test is about the line
  OnlineCalibrationEstimator estimator(online, recording.camera, truthAt(recording, 0.0));
  double worst_estimate_ms = 0.0, worst_in_use_ms = 0.0;
  replay(recording, estimator, [&](double t) {
    if (t < 10.0) return;
    const double truth_s = recording.time_offset_s(t);
    worst_estimate_ms = std::max(worst_estimate_ms, std::abs(estimator.status().estimate.time_offset_s - truth_s) * 1e3);
    // As a frame at t gets it: the line at t (the calibration in use carries the drift rate).
    worst_in_use_ms = std::max(worst_in_use_ms, std::abs(estimator.status().in_use.timeOffsetAt(t) - truth_s) * 1e3);
  });
  say("drift 3 ms/min, 40 s (truth at the end)", estimator.status(), truthAt(recording, 40.0));
  std::cout << "[ measured ] after 10 s: worst estimate error " << worst_estimate_ms << " ms, in use "
            << worst_in_use_ms << " ms (the offset drifted 2 ms)\n";
  EXPECT_LT(worst_estimate_ms, 0.5);
  // Issue 33's target holds for the calibration in use, not only the estimate: it follows by
  // refinements of the offset once it is 0.15 ms off the estimate (0.83 ms before the readout was
  // held and the offset refined on its own; 0.35 ms now).
  EXPECT_LT(worst_in_use_ms, 0.5);
  EXPECT_GT(estimator.status().refinements, 0u);
  // The calibration in use carries the drift (50 us/s): a frame a second later gets that much more
  // offset, and a stamp on another timeline (time went back by more than a second) the offset at
  // the reference.
  const CameraImuCalibration& in_use = estimator.status().in_use;
  std::cout << "[ measured ] drift rate in use " << in_use.time_offset_rate * 1e6 << " us/s (true 50)\n";
  EXPECT_NEAR(in_use.time_offset_rate, 50e-6, 25e-6);
  const double reference_s = in_use.time_offset_reference_s;
  EXPECT_DOUBLE_EQ(in_use.timeOffsetAt(reference_s), in_use.time_offset_s);
  EXPECT_NEAR(in_use.timeOffsetAt(reference_s + 1.0) - in_use.time_offset_s, in_use.time_offset_rate, 1e-12);
  EXPECT_NEAR(in_use.timeOffsetAt(reference_s - 0.5) - in_use.time_offset_s, -0.5 * in_use.time_offset_rate, 1e-12);
  EXPECT_EQ(in_use.timeOffsetAt(reference_s - 30.0), in_use.time_offset_s);
  EXPECT_EQ(in_use.heldAt(reference_s + 2.0).time_offset_rate, 0.0);
}

TEST(OnlineCalibrationEstimator, AConstantOffsetIsAppliedWhenTheRateIsNot) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 20.0;
  options.seed = 4;
  options.extra_offset_s = [](double t) { return 3e-3 * t / 60.0; };
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.estimate_rotation = false;
  online.apply_drift_rate = false;
  OnlineCalibrationEstimator estimator(online, recording.camera, truthAt(recording, 0.0));
  replay(recording, estimator);
  EXPECT_GT(estimator.status().swaps, 0u);
  EXPECT_EQ(estimator.status().in_use.time_offset_rate, 0.0);
  EXPECT_EQ(estimator.status().estimate.time_offset_rate, 0.0);
}

TEST(OnlineCalibrationEstimator, ReconvergesAfterATenMillisecondJump) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 30.0;
  options.seed = 5;
  constexpr double kJumpS = 12.0;
  options.extra_offset_s = [](double t) { return t >= kJumpS ? 0.010 : 0.0; };
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.estimate_rotation = false;
  OnlineCalibrationEstimator estimator(online, recording.camera, truthAt(recording, 0.0));
  double back_at_s = -1.0;
  replay(recording, estimator, [&](double t) {
    if (t < kJumpS) return;
    const bool close = std::abs(estimator.status().in_use.timeOffsetAt(t) - recording.time_offset_s(t)) < 0.5e-3;
    if (close && back_at_s < 0.0) back_at_s = t;
    if (!close) back_at_s = -1.0;
  });
  say("10 ms jump at 12 s", estimator.status(), truthAt(recording, 30.0));
  std::cout << "[ measured ] in use within 0.5 ms again " << back_at_s - kJumpS << " s after the jump\n";
  EXPECT_GE(estimator.status().jumps, 1u);
  ASSERT_GE(back_at_s, kJumpS);
  EXPECT_LT(back_at_s - kJumpS, 10.0);
}

TEST(OnlineCalibrationEstimator, AStillCameraHoldsItsCalibrationAndNeedsMotion) {
  sim::SimulatorConfig config = handHeldCamera(false);
  config.motion.shake_rms_rad_s.setZero();
  config.motion.pan_peak_rad_s = 0.0;
  sim::SyntheticTrackOptions options;
  options.duration_s = 10.0;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(config, options);
  const CameraImuCalibration start = wrongStart(recording);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, start);
  replay(recording, estimator);
  const OnlineCalibrationStatus& status = estimator.status();
  say("still camera", status, truthAt(recording, 0.0));
  EXPECT_EQ(status.state, "needs motion");
  EXPECT_GT(status.fits_needing_motion, 0u);
  EXPECT_EQ(status.version, 0u);
  EXPECT_EQ(status.in_use.time_offset_s, start.time_offset_s);
  EXPECT_EQ(status.in_use.readout_time_s, start.readout_time_s);
  EXPECT_TRUE(status.in_use.imu_to_camera_rotation.isApprox(start.imu_to_camera_rotation));
}

TEST(OnlineCalibrationEstimator, ATexturelessCameraHoldsItsCalibrationAndNeedsMotion) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 8.0;
  options.tracks_per_pair = 5;  // below the calibration's 12 tracks per pair
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  const CameraImuCalibration start = wrongStart(recording);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, start);
  replay(recording, estimator);
  const OnlineCalibrationStatus& status = estimator.status();
  EXPECT_EQ(status.state, "needs motion");
  EXPECT_EQ(status.pairs_without_tracks, recording.pairs.size());
  EXPECT_EQ(status.version, 0u);
  EXPECT_EQ(status.in_use.time_offset_s, start.time_offset_s);
}

TEST(OnlineCalibrationEstimator, ALoopedTimelineKeepsTheEstimate) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 12.0;
  options.seed = 6;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, wrongStart(recording));
  replay(recording, estimator);
  const CameraImuCalibration after_first = estimator.status().in_use;
  // The same stamps again without a restart are older than the last pair: ignored.
  const std::size_t pairs = estimator.status().pairs;
  estimator.addPair({recording.pairs[0].stamp_a_s, recording.pairs[0].stamp_b_s, recording.pairs[0].matches});
  EXPECT_EQ(estimator.status().pairs, pairs);
  estimator.restartTimeline();
  replay(recording, estimator);
  const CameraImuCalibration truth = truthAt(recording, 0.0);
  EXPECT_NEAR(estimator.status().in_use.time_offset_s, truth.time_offset_s, 0.5e-3);
  EXPECT_LE(std::abs(estimator.status().in_use.time_offset_s - truth.time_offset_s),
            std::abs(after_first.time_offset_s - truth.time_offset_s) + 0.3e-3);
}

TEST(OnlineCalibrationEstimator, StaysWithinItsCpuShare) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 20.0;
  options.seed = 7;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationOptions online = unbudgeted();
  online.cpu_share = 0.02;  // far below what a fit every 1.5 s costs
  OnlineCalibrationEstimator estimator(online, recording.camera, wrongStart(recording));
  double worst_excess_s = 0.0, longest_fit_s = 0.0;
  replay(recording, estimator, [&](double) {
    // From the start to any moment: what was spent beyond the share's credit is at most one fit
    // (the budget decides before a fit, never during one). A fit's cost depends on the machine's
    // load, so the bound is the longest fit measured here (its wall time bounds its CPU time).
    const OnlineCalibrationStatus& status = estimator.status();
    worst_excess_s = std::max(worst_excess_s, status.cpu_s - online.cpu_share * status.stream_s);
    longest_fit_s = std::max(longest_fit_s, status.last_fit_seconds);
  });
  const OnlineCalibrationStatus& status = estimator.status();
  std::cout << "[ measured ] share 2 %: " << status.cpu_s << " s CPU over " << status.stream_s << " s, " << status.fits
            << " fits, " << status.fits_over_budget << " waited; worst excess " << worst_excess_s << " s\n";
  EXPECT_GT(status.fits_over_budget, 0u);
  EXPECT_GT(status.fits, 0u);
  EXPECT_LT(status.cpu_s, online.cpu_share * status.stream_s + longest_fit_s + 0.05);
  EXPECT_LT(worst_excess_s, longest_fit_s + 0.05);  // one fit at most (0.1-0.6 s here)
}

// The live path: the learner's tracking thread hands every tracked pair to the estimator
// (OnlineLearningOptions::on_tracked_pair + feedTrackedPair), the gyro as the gyro flow sends it
// (camera frame, rotated with the wrong mount in use, IMU clock), all within the learner's budget.
TEST(OnlineCalibrationEstimator, RunsOnTheLearnersTrackingThread) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 20.0;
  options.seed = 8;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  const CameraImuCalibration start = wrongStart(recording);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, start);
  std::atomic<double> clock_s{0.0};
  OnlineLearningOptions learning;
  learning.learning = false;  // checks only: the calibration is what runs here
  learning.cpu_share = 1.0;
  learning.budget_clock = [&clock_s] { return clock_s.load(); };
  learning.on_tracked_pair = [&estimator](const OnlineFramePair& pair) { feedTrackedPair(pair, estimator); };
  OnlineStabiliserLearner learner(learning, {{"no lens motion", noLensMotion()}}, 0);
  std::size_t next_gyro = 0;
  std::vector<CameraRateSample> recent;
  for (const sim::SyntheticTrackPair& synthetic : recording.pairs) {
    OnlineFramePair pair;
    pair.stamp_a_s = synthetic.stamp_a_s;
    pair.stamp_b_s = synthetic.stamp_b_s;
    pair.timing.time_offset_s = start.time_offset_s;
    pair.timing.readout_time_s = start.readout_time_s;
    pair.timing.imu_to_camera_rotation = start.imu_to_camera_rotation;
    pair.camera = recording.camera;
    // The gyro flow's rates: raw samples rotated by the rotation in use, up to 0.2 s past frame b.
    const double until_s = synthetic.stamp_b_s + recording.time_offset_s(synthetic.stamp_b_s) + 0.2;
    while (next_gyro < recording.gyro.size() && recording.gyro[next_gyro].stamp_s <= until_s) {
      const ImuSample& sample = recording.gyro[next_gyro++];
      recent.push_back({sample.stamp_s, start.imu_to_camera_rotation * sample.angular_velocity_rad_s});
    }
    if (recent.size() > 400) recent.erase(recent.begin(), recent.end() - 400);
    pair.rates = recent;
    pair.matches = synthetic.matches;
    pair.tracked = true;
    clock_s = synthetic.stamp_b_s;
    ASSERT_TRUE(learner.submit(std::move(pair)));
    ASSERT_TRUE(learner.waitIdle(30.0));
  }
  const OnlineLearningStatus learning_status = learner.status();
  const OnlineCalibrationStatus& status = estimator.status();
  const CameraImuCalibration truth = truthAt(recording, 0.0);
  say("through the learner, 20 s", status, truth);
  std::cout << "[ measured ] learner: " << learning_status.pairs_submitted << " pairs submitted, "
            << learning_status.pairs_over_budget << " skipped over budget, CPU " << learning_status.cpu_s << " s\n";
  EXPECT_GT(status.pairs, recording.pairs.size() / 2);
  EXPECT_EQ(status.mount_permutation_index, nearestSignedAxisPermutation(truth.imu_to_camera_rotation));
  EXPECT_NEAR(status.in_use.time_offset_s, truth.time_offset_s, 0.75e-3);
  EXPECT_NEAR(status.in_use.readout_time_s, truth.readout_time_s, 1e-3);
  // The calibration's CPU is the learner's: charged to its budget with the tracking.
  EXPECT_GE(learning_status.cpu_s, 0.8 * status.cpu_s);
}

// An undo (the session's per-pair check found a swap worse) rewinds the estimator to the state it
// had before the fit that offered the swap: the calibration in use then, the estimate and the clock
// model; the data stay, the version does not go back, and a second rewind of the same swap does
// nothing.
TEST(OnlineCalibrationEstimator, AnUndoRewindsToTheStateBeforeTheUndoneStep) {
  sim::SyntheticTrackOptions options;
  options.duration_s = 20.0;
  options.seed = 8;
  const sim::SyntheticTrackRecording recording = sim::makeSyntheticTrackRecording(handHeldCamera(false), options);
  OnlineCalibrationEstimator estimator(unbudgeted(), recording.camera, wrongStart(recording));
  // The status and clock model before each update that fitted (the swap's candidate comes from the
  // last fit before the update that scored it: an update scores first, then fits).
  struct Before {
    OnlineCalibrationStatus status;
    ClockOffsetFilter clock;
  };
  Before before_last_fit{estimator.status(), estimator.clockModel()};
  std::size_t next_gyro = 0;
  bool swapped = false;
  Before before_swap_fit = before_last_fit;
  OnlineCalibrationStatus after_swap;
  for (const sim::SyntheticTrackPair& pair : recording.pairs) {
    const double gyro_until_s = pair.stamp_b_s + recording.time_offset_s(pair.stamp_b_s) + 0.2;
    while (next_gyro < recording.gyro.size() && recording.gyro[next_gyro].stamp_s <= gyro_until_s) {
      estimator.addGyro(recording.gyro[next_gyro++]);
    }
    const Before before{estimator.status(), estimator.clockModel()};
    estimator.addPair({pair.stamp_a_s, pair.stamp_b_s, pair.matches});
    const std::size_t fits_before = estimator.status().fits;
    const bool changed = estimator.update();
    const bool fitted = estimator.status().fits != fits_before;
    if (changed) {
      // Scored before this update's own fit: the candidate is the last fit's.
      before_swap_fit = before_last_fit;
      after_swap = estimator.status();
      swapped = true;
      break;
    }
    if (fitted) before_last_fit = before;
  }
  ASSERT_TRUE(swapped) << "no swap in 20 s from the wrong start";
  ASSERT_EQ(after_swap.version, 1u);
  EXPECT_NE(after_swap.in_use.time_offset_s, before_swap_fit.status.in_use.time_offset_s);

  EXPECT_FALSE(estimator.rewindBeforeSwap(2));  // no such swap: nothing changes
  EXPECT_EQ(estimator.status().in_use.time_offset_s, after_swap.in_use.time_offset_s);
  ASSERT_TRUE(estimator.rewindBeforeSwap(1));
  const OnlineCalibrationStatus& rewound = estimator.status();
  EXPECT_EQ(rewound.in_use.time_offset_s, before_swap_fit.status.in_use.time_offset_s);
  EXPECT_EQ(rewound.in_use.readout_time_s, before_swap_fit.status.in_use.readout_time_s);
  EXPECT_TRUE(rewound.in_use.imu_to_camera_rotation.isApprox(before_swap_fit.status.in_use.imu_to_camera_rotation));
  EXPECT_EQ(rewound.estimate.time_offset_s, before_swap_fit.status.estimate.time_offset_s);
  EXPECT_EQ(rewound.estimate.time_offset_sigma_s, before_swap_fit.status.estimate.time_offset_sigma_s);
  EXPECT_EQ(rewound.estimate.readout_time_s, before_swap_fit.status.estimate.readout_time_s);
  EXPECT_EQ(rewound.mount_found, before_swap_fit.status.mount_found);
  EXPECT_EQ(estimator.clockModel().initialised(), before_swap_fit.clock.initialised());
  if (before_swap_fit.clock.initialised()) {
    EXPECT_EQ(estimator.clockModel().offsetAt(10.0), before_swap_fit.clock.offsetAt(10.0));
    EXPECT_EQ(estimator.clockModel().rate(), before_swap_fit.clock.rate());
    EXPECT_EQ(estimator.clockModel().noiseScale(), before_swap_fit.clock.noiseScale());
  }
  EXPECT_EQ(rewound.version, 1u);  // it counts swaps; the session applies the replaced state
  EXPECT_EQ(rewound.rewinds, 1u);
  EXPECT_EQ(rewound.pairs, after_swap.pairs);  // the data stay
  EXPECT_FALSE(estimator.rewindBeforeSwap(1));  // once only
  EXPECT_EQ(estimator.status().rewinds, 1u);
}

TEST(OnlineCalibrationEstimator, BadInputIsNamed) {
  CameraModel camera = sim::nominalCamera(sim::SensorConfig{});
  OnlineCalibrationOptions options;
  options.window_s = 0.1;
  try {
    OnlineCalibrationEstimator estimator(options, camera, {});
    FAIL() << "expected a refusal";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("window_s"), std::string::npos) << error.what();
  }
  CameraImuCalibration bad;
  bad.readout_time_s = -1.0;
  EXPECT_THROW(OnlineCalibrationEstimator({}, camera, bad), std::invalid_argument);
  options = {};
  options.refit_every_s = 10.0;  // longer than the window
  EXPECT_THROW(OnlineCalibrationEstimator(options, camera, {}), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
