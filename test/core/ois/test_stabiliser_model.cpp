// The learned stabiliser model (core/ois/): its state across frames and gaps, its physics on a
// case with a closed form, the fit recovering a known stabiliser, the model file and the camera
// check, and the compensated homographies.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/ois/camera_rate_cursor.h"
#include "deep_ois/core/ois/lens_log_time_fit.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/stroke.h"
#include "known_stabiliser.h"

namespace deep_ois {
namespace {

constexpr double kFocalPx = 300.0;

// A hand-shake-like rate stream: a few sines per axis, 400 Hz, from t0 for duration_s.
std::vector<CameraRateSample> shake(double t0, double duration_s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> phase(0.0, 6.283), amplitude(0.02, 0.12);
  const double frequencies[] = {0.7, 2.3, 5.1, 9.0};
  double a[2][4], p[2][4];
  for (int axis = 0; axis < 2; ++axis)
    for (int k = 0; k < 4; ++k) a[axis][k] = amplitude(rng), p[axis][k] = phase(rng);
  std::vector<CameraRateSample> rates;
  for (double t = 0.0; t <= duration_s; t += 1.0 / 400.0) {
    CameraRateSample sample;
    sample.stamp_s = t0 + t;
    for (int axis = 0; axis < 2; ++axis)
      for (int k = 0; k < 4; ++k)
        sample.rate_rad_s(axis) += 6.0 * a[axis][k] * std::sin(6.283 * frequencies[k] * t + p[axis][k]);
    sample.rate_rad_s.z() = 0.05 * std::sin(3.0 * t);
    rates.push_back(sample);
  }
  return rates;
}

TEST(LensShiftPredictor, FeedingFrameByFrameCarriesTheStateExactly) {
  const auto rates = shake(10.0, 3.0, 1);
  LensShiftPredictor whole(knownStabiliser(), kFocalPx), framewise(knownStabiliser(), kFocalPx);
  for (const auto& r : rates) whole.addRate(r);
  // As the nodelet feeds it: the samples of each 33 ms frame interval, queried in between.
  double max_difference = 0.0;
  std::size_t k = 0;
  for (double frame_end = 10.0; k < rates.size(); frame_end += 1.0 / 30.0) {
    while (k < rates.size() && rates[k].stamp_s <= frame_end) framewise.addRate(rates[k++]);
    if (framewise.covers(frame_end - 0.01) && k == rates.size()) {
      max_difference = std::max(max_difference, (framewise.lensShiftAt(frame_end - 0.01) -
                                                 whole.lensShiftAt(frame_end - 0.01)).norm());
    }
  }
  EXPECT_EQ(framewise.resets(), 0);
  EXPECT_LT(max_difference, 1e-12);
  // The lens moved (a shake this strong moves it by pixels) and stayed within its stroke.
  const Eigen::Vector2d end = whole.lensShiftAt(12.9);
  EXPECT_GT(end.norm(), 0.1);
  EXPECT_LE(std::abs(end.x()), kFocalPx * std::tan(0.8 * M_PI / 180.0) + 1e-9);
}

TEST(LensShiftPredictor, AnswersUpToItsNewestSampleWhateverTheSampleTiming) {
  // Samples off the internal 1 ms grid (a 400 Hz IMU with a 0.3 ms phase): a pair's last patch
  // just before the newest sample must be answered (the evaluator once lost every third pair).
  LensShiftPredictor predictor(knownStabiliser(), kFocalPx);
  for (double t = 0.0003; t < 0.5; t += 0.0025) predictor.addRate({t, Eigen::Vector3d(0.1, 0.1, 0.0)});
  const double newest = predictor.newestStamp();
  EXPECT_TRUE(predictor.covers(newest - 1e-4));
  EXPECT_TRUE(predictor.covers(newest));
  EXPECT_FALSE(predictor.covers(newest + 1e-3));
  EXPECT_TRUE(predictor.lensShiftAt(newest).allFinite());
}

TEST(LensShiftPredictor, AGapInTheGyroRestartsFromACentredLens) {
  LensShiftPredictor predictor(knownStabiliser(), kFocalPx);
  for (const auto& r : shake(0.0, 1.0, 2)) predictor.addRate(r);
  EXPECT_GT(predictor.lensShiftAt(predictor.newestStamp()).norm(), 0.01);
  const int before = predictor.resets();
  // 0.5 s without a sample (> max_gap_s): the state across it is unknown.
  CameraRateSample after;
  after.stamp_s = predictor.newestStamp() + 0.5;
  after.rate_rad_s = Eigen::Vector3d(0.3, -0.2, 0.0);
  EXPECT_TRUE(predictor.addRate(after));
  EXPECT_EQ(predictor.resets(), before + 1);
  EXPECT_FALSE(predictor.covers(after.stamp_s - 0.1));  // nothing before the gap is answered
  EXPECT_NEAR(predictor.lensShiftAt(after.stamp_s).norm(), 0.0, 1e-12);
  // Out-of-order and non-finite samples are ignored, not fed.
  CameraRateSample old = after;
  old.stamp_s -= 0.01;
  EXPECT_FALSE(predictor.addRate(old));
  CameraRateSample bad = after;
  bad.stamp_s += 0.01;
  bad.rate_rad_s.x() = std::nan("");
  EXPECT_FALSE(predictor.addRate(bad));
}

TEST(LensShiftPredictor, ACentringFreeStabiliserCancelsAConstantTurnExactly) {
  // No centring, a stiff actuator, a stroke out of reach: after a turn of theta about y the lens
  // sits at f tan(theta) in x (the cancelling shift of the package's convention).
  StabiliserModel p;
  p.get<CentringValues>().highpass_corner_hz = 0.0;
  p.get<ActuatorValues>().actuator_natural_hz = 400.0;
  p.get<ActuatorValues>().actuator_damping = 1.0;
  p.get<StrokeValues>().stroke_x_deg = p.get<StrokeValues>().stroke_y_deg = 10.0;
  LensShiftPredictor predictor(p, kFocalPx);
  const double rate = 0.2;  // rad/s about y for 0.5 s: 0.1 rad
  for (double t = 0.0; t <= 0.5 + 1e-9; t += 0.0025) predictor.addRate({t, Eigen::Vector3d(0.0, rate, 0.0)});
  for (double t = 0.5025; t <= 0.7; t += 0.0025) predictor.addRate({t, Eigen::Vector3d::Zero()});
  // The rate is linear between samples: the ramp to 0 after 0.5 s adds half a sample interval.
  const double theta = 0.1 + 0.5 * rate * 0.0025;
  const Eigen::Vector2d shift = predictor.lensShiftAt(0.7);
  EXPECT_NEAR(shift.x(), kFocalPx * std::tan(theta), 0.01);
  EXPECT_NEAR(shift.y(), 0.0, 1e-9);
}

// Observations a stabiliser of `truth` gives on 30 fps frames with 6 row patches, plus noise.
StabiliserFitRecording observe(const StabiliserModel& truth, unsigned seed, double noise_px) {
  StabiliserFitRecording recording;
  recording.name = "synthetic " + std::to_string(seed);
  recording.focal_px = kFocalPx;
  recording.rates = shake(0.0, 6.0, seed);
  std::mt19937 rng(seed + 100);
  std::normal_distribution<double> noise(0.0, noise_px);
  for (double stamp = 0.0; stamp + 1.0 / 30.0 < 5.9; stamp += 1.0 / 30.0) {
    for (int i = 0; i < 6; ++i) {
      LensMotionObservation o;
      o.t_a_s = stamp + 0.02 * (i + 0.5) / 6.0;
      o.t_b_s = o.t_a_s + 1.0 / 30.0;
      recording.observations.push_back(o);
    }
  }
  const auto motion = predictLensMotion(truth, recording, 1e-3, 0.0);
  for (std::size_t k = 0; k < motion.size(); ++k)
    recording.observations[k].motion_px = motion[k] + Eigen::Vector2d(noise(rng), noise(rng));
  return recording;
}

TEST(StabiliserFit, RecoversAKnownStabiliserFromNoisyLensMotion) {
  const StabiliserModel truth = knownStabiliser();
  const std::vector<StabiliserFitRecording> training = {observe(truth, 11, 0.05),
                                                        observe(truth, 12, 0.05)};
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};  // keep the test short: no pan-detection candidates
  options.try_circular_stroke = false;
  options.iterations = 20;
  const StabiliserFitResult fit = fitStabiliser(training, options);
  std::printf("fit: rms without model %.3f px, with the model %.3f px\n", fit.rms_without_model_px,
              fit.rms_px);
  EXPECT_GT(fit.rms_without_model_px, 0.5);
  EXPECT_LT(fit.rms_px, 0.1);  // the noise (0.05 px per axis) and little more
  EXPECT_NEAR(fit.parameters.get<CentringValues>().gain(0, 1), 0.9, 0.05);
  EXPECT_NEAR(fit.parameters.get<CentringValues>().gain(1, 0), -1.05, 0.05);
  EXPECT_NEAR(fit.parameters.get<CentringValues>().highpass_corner_hz, 0.8, 0.15);
  // A held-out recording of the same stabiliser is predicted as well as the training ones.
  const StabiliserFitRecording held_out = observe(truth, 13, 0.0);
  const auto predicted = predictLensMotion(fit.parameters, held_out, 1e-3, 1.0);
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = 0; k < predicted.size(); ++k) {
    if (!predicted[k].allFinite()) continue;
    sum += (predicted[k] - held_out.observations[k].motion_px).squaredNorm();
    ++n;
  }
  ASSERT_GT(n, 100);
  EXPECT_LT(std::sqrt(sum / n), 0.1);
}

// Issue 23 #4: a lens log in active-array pixels read with lens_shift_scale 1 trained silently to
// a gain of 6.6 and a 9.8 deg stroke, with the sensor lag and the actuator damping on their bounds.
TEST(StabiliserFit, ReviewNamesImplausibleValuesAndParametersOnABound) {
  StabiliserModel p = knownStabiliser();
  p.get<CentringValues>().gain << 0.0, 6.6, -6.4, 0.0;
  p.get<StrokeValues>().stroke_x_deg = 9.8;
  p.get<ActuatorValues>().sensor_lag_s = 0.0;
  p.get<ActuatorValues>().actuator_damping = 0.05;
  const StabiliserFitReview review = reviewStabiliserFit(p, LensMotionTarget::kLensLog);
  ASSERT_EQ(review.implausible.size(), 2u);
  EXPECT_NE(review.implausible[0].find("gain"), std::string::npos) << review.implausible[0];
  EXPECT_NE(review.implausible[0].find("lens_shift_scale"), std::string::npos);
  EXPECT_NE(review.implausible[1].find("stroke 9.8"), std::string::npos) << review.implausible[1];
  EXPECT_TRUE(review.onBound("sensor_lag_s"));
  EXPECT_TRUE(review.onBound("actuator_damping"));
  EXPECT_FALSE(review.onBound("highpass_corner_hz"));
  EXPECT_EQ(review.on_bound.size(), 2u);
  // A module as the simulator's: nothing to say.
  const StabiliserFitReview plausible = reviewStabiliserFit(knownStabiliser());
  EXPECT_TRUE(plausible.implausible.empty());
  EXPECT_TRUE(plausible.on_bound.empty());
}

// Issue 31 #4: the review blames only what the lens motions' source can get wrong. Lens motions
// from the images have no lens log, so no lens_shift_scale; the simulator's truth has neither a
// log nor a calibration to run.
TEST(StabiliserFit, ReviewBlamesOnlyWhatTheTargetCanGetWrong) {
  StabiliserModel p = knownStabiliser();
  p.get<CentringValues>().gain << 0.0, 6.6, -6.4, 0.0;
  p.get<StrokeValues>().stroke_x_deg = 9.8;
  p.get<ActuatorValues>().sensor_lag_s = 0.0;
  const StabiliserFitReview images = reviewStabiliserFit(p);  // the default target: the images
  ASSERT_EQ(images.implausible.size(), 2u);
  for (const std::string& line : images.implausible) {
    EXPECT_EQ(line.find("lens_shift"), std::string::npos) << line;
    EXPECT_EQ(line.find("lens log"), std::string::npos) << line;
    EXPECT_NE(line.find("run calibrate"), std::string::npos) << line;
  }
  for (const std::string& line : reviewStabiliserFit(p, LensMotionTarget::kSimulatorTruth).implausible) {
    EXPECT_EQ(line.find("lens_shift"), std::string::npos) << line;
    EXPECT_EQ(line.find("calibrate"), std::string::npos) << line;
  }
  const StabiliserFitReview log = reviewStabiliserFit(p, LensMotionTarget::kLensLog);
  EXPECT_NE(log.on_bound.front().find("lens_shift_time_offset"), std::string::npos) << log.on_bound.front();
  EXPECT_EQ(images.on_bound.front().find("lens_shift_time_offset"), std::string::npos) << images.on_bound.front();
  // A lens that hardly moves: OIS off, for every target; only a log can be on the wrong scale.
  p.get<CentringValues>().gain << 0.0, 0.01, -0.01, 0.0;
  p.get<StrokeValues>().stroke_x_deg = 1.0;
  const StabiliserFitReview still = reviewStabiliserFit(p);
  ASSERT_FALSE(still.implausible.empty());
  EXPECT_NE(still.implausible.front().find("OIS was likely off"), std::string::npos) << still.implausible.front();
  EXPECT_EQ(still.implausible.front().find("lens_shift_scale"), std::string::npos) << still.implausible.front();
}

// The timing check's line says when its best value is the end of the range it scanned (the VIC
// recording printed "readout changed by -20 ms", which is no finding).
TEST(StabiliserFit, TimingSummarySaysWhenTheScanEndedOnItsEdge) {
  StabiliserFitReview review;
  EXPECT_EQ(timingCheckSummary(review), "timing check: not run");
  review.best_lens_lag_ms = -2.6;
  review.best_readout_change_ms = -20.0;
  const std::string line = timingCheckSummary(review);
  EXPECT_NE(line.find("2.6 ms ahead of the gyro"), std::string::npos) << line;
  EXPECT_NE(line.find("-20.0 ms (the end of the +-20.0 ms scanned: no optimum inside it)"), std::string::npos)
      << line;
}

// The same from the fit itself: lens motions 6.6 times too large (the wrong scale) are fitted,
// and the result says its gain is implausible.
TEST(StabiliserFit, LensMotionsOnTheWrongScaleAreFlagged) {
  StabiliserFitRecording recording = observe(knownStabiliser(), 21, 0.02);
  for (LensMotionObservation& o : recording.observations) o.motion_px *= 6.6;
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 10;
  const StabiliserFitResult fit = fitStabiliser({recording}, options);
  ASSERT_FALSE(fit.review.implausible.empty());
  EXPECT_NE(fit.review.implausible[0].find("gain"), std::string::npos) << fit.review.implausible[0];
}

// Observations of `truth` on 30 fps frames whose rows were captured with `true_readout_s`, placed
// in time with the gyro config's `config_readout_s` (issue 23 #12: a wrong readout hides in the
// fitted lens).
// `early_s`: the config places the frames this much before their true capture (a time offset
// error).
StabiliserFitRecording observeWithReadout(const StabiliserModel& truth, unsigned seed,
                                          double true_readout_s, double config_readout_s,
                                          double early_s = 0.0) {
  StabiliserFitRecording recording;
  recording.name = "synthetic " + std::to_string(seed);
  recording.focal_px = kFocalPx;
  recording.rates = shake(0.0, 6.0, seed);
  for (double stamp = 0.0; stamp + 1.0 / 30.0 < 5.9; stamp += 1.0 / 30.0) {
    for (int i = 0; i < 6; ++i) {
      LensMotionObservation o;
      o.readout_fraction = (i + 0.5) / 6.0;
      o.t_a_s = stamp + true_readout_s * o.readout_fraction;
      o.t_b_s = o.t_a_s + 1.0 / 30.0;
      recording.observations.push_back(o);
    }
  }
  const auto motion = predictLensMotion(truth, recording, 1e-3, 0.0);
  for (std::size_t k = 0; k < motion.size(); ++k) {
    LensMotionObservation& o = recording.observations[k];
    o.motion_px = motion[k];
    const double placed =
        o.t_a_s + (config_readout_s - true_readout_s) * o.readout_fraction - early_s;
    o.t_b_s += placed - o.t_a_s;
    o.t_a_s = placed;
  }
  return recording;
}

StabiliserFitResult fitWithReadout(double true_readout_s, double config_readout_s,
                                   double early_s = 0.0) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 10;
  options.readout_time_s = config_readout_s;
  const StabiliserModel truth = knownStabiliser();  // 2 ms sensor lag
  return fitStabiliser({observeWithReadout(truth, 31, true_readout_s, config_readout_s, early_s),
                        observeWithReadout(truth, 32, true_readout_s, config_readout_s, early_s)},
                       options);
}

TEST(StabiliserFit, TimingCheckPassesTheRightReadout) {
  const StabiliserFitResult fit = fitWithReadout(0.012, 0.012);
  EXPECT_TRUE(fit.review.timing.empty()) << fit.review.timing.front();
  EXPECT_NEAR(fit.review.best_readout_change_ms, 0.0, 1.0);
  EXPECT_NEAR(fit.review.best_lens_lag_ms, 2.0, 1.0);  // the module's own lag
}

// A 60 fps camera with a 12 ms readout trained with the default 22 ms: the lens absorbed the
// error and the track residual looked fine; the timing check names the readout.
TEST(StabiliserFit, TimingCheckNamesAReadoutTooLong) {
  const StabiliserFitResult fit = fitWithReadout(0.012, 0.022);
  EXPECT_NEAR(fit.review.best_readout_change_ms, -10.0, 2.0);
  ASSERT_FALSE(fit.review.timing.empty());
  EXPECT_EQ(fit.review.timing.front().rfind("readout_time:", 0), 0u) << fit.review.timing.front();
  EXPECT_NE(fit.review.timing.front().find("config says 22.0 ms"), std::string::npos)
      << fit.review.timing.front();
}

// A 30 ms camera trained with 22 ms: the fit hid the error as a longer sensor lag.
TEST(StabiliserFit, TimingCheckNamesAReadoutTooShort) {
  const StabiliserFitResult fit = fitWithReadout(0.030, 0.022);
  EXPECT_NEAR(fit.review.best_readout_change_ms, 8.0, 2.0);
  ASSERT_FALSE(fit.review.timing.empty());
  EXPECT_EQ(fit.review.timing.front().rfind("readout_time:", 0), 0u) << fit.review.timing.front();
}

// Issue 25: "no lens motion" is always a candidate. A camera with OIS off (lens motions that are
// noise) fits some lens anyway; on held-out recordings it does not beat no lens motion and is
// refused, with the reason. A camera with OIS keeps its fit.
// A time offset 6 ms late: the lens seems to lag its gyro by 8 ms, more than a module's sensor
// lag (the fit hid it as a sensor lag); the readout is right and not named.
TEST(StabiliserFit, TimingCheckNamesATimeOffsetError) {
  const StabiliserFitResult late = fitWithReadout(0.012, 0.012, -0.006);
  EXPECT_NEAR(late.review.best_lens_lag_ms, 8.0, 1.0);
  ASSERT_EQ(late.review.timing.size(), 1u);
  EXPECT_EQ(late.review.timing.front().rfind("time_offset:", 0), 0u) << late.review.timing.front();
  // 6 ms early: the actuator's own delay (about 6 ms for the 30 Hz, 0.6 damping truth) absorbs a
  // lead that large, so the timing check cannot tell it; the fit ends on its bounds instead.
  const StabiliserFitResult early = fitWithReadout(0.012, 0.012, 0.006);
  for (const std::string& line : early.review.timing)
    EXPECT_EQ(line.rfind("readout_time:", 0), std::string::npos) << line;
  EXPECT_TRUE(early.review.onBound("sensor_lag_s"));
}

// Issue 31 #5: a lens log whose clock is late against the gyro. The timing check names
// lens_shift_time_offset (not calibrate, which needs images) with the value to add, and the shared
// timing fit (lens_log_fit and train_stabiliser --fit-time-offset) moves the log back onto the gyro.
TEST(LensLogTimeFit, MovesALateLensLogOntoTheGyroAndSaysTheOffsetToSet) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 10;
  options.readout_time_s = 0.012;
  options.target = LensMotionTarget::kLensLog;
  const StabiliserModel truth = knownStabiliser();  // 2 ms sensor lag
  // The log's stamps 6 ms late: the lens seems to lag its gyro by 8 ms.
  const std::vector<StabiliserFitRecording> logged = {observeWithReadout(truth, 31, 0.012, 0.012, -0.006),
                                                      observeWithReadout(truth, 32, 0.012, 0.012, -0.006)};
  const StabiliserFitResult as_logged = fitStabiliser(logged, options);
  ASSERT_EQ(as_logged.review.timing.size(), 1u);
  const std::string& advice = as_logged.review.timing.front();
  EXPECT_EQ(advice.rfind("lens_shift_time_offset:", 0), 0u) << advice;
  EXPECT_NE(advice.find("add -0.00"), std::string::npos) << advice;
  EXPECT_EQ(advice.find("run calibrate"), std::string::npos) << advice;

  const LensLogTimeFit timed = fitStabiliserAndLensLogTime(
      [&](double moved_s) { return withLensLogMoved(logged, moved_s); }, options);
  EXPECT_NEAR(timed.lag_before_ms, 8.0, 1.0);
  EXPECT_NEAR(timed.moved_s, -0.008, 0.001);
  EXPECT_TRUE(timed.fit.review.timing.empty()) << timed.fit.review.timing.front();
  const std::string set = lensShiftTimeOffsetAdvice(0.001, timed.moved_s);
  EXPECT_EQ(set.rfind("lens_shift_time_offset: -0.00", 0), 0u) << set;
  EXPECT_NE(set.find("camera time = logged stamp + lens_shift_time_offset"), std::string::npos) << set;
}

TEST(StabiliserFit, AFitThatDoesNotBeatNoLensMotionOnHeldOutRecordingsIsRefused) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 10;
  StabiliserModel off = knownStabiliser();
  off.get<CentringValues>().gain.setZero();  // the lens never moves: only the noise of the measurement is left
  const StabiliserFitResult ois_off = fitStabiliser({observe(off, 41, 0.1)}, options);
  const NoLensMotionCheck off_check =
      checkFitAgainstNoLensMotion(ois_off.parameters, {observe(off, 41, 0.1)}, {observe(off, 42, 0.1)}, options);
  // A lens fitted to noise has no timing to check (it named a 16 ms time offset error).
  EXPECT_TRUE(ois_off.review.timing.empty()) << ois_off.review.timing.front();
  EXPECT_TRUE(off_check.refused) << off_check.reason;
  EXPECT_FALSE(off_check.reason.empty());
  // No lens motion predicts exactly that.
  const StabiliserScore none = scoreStabiliser(noLensMotion(), {observe(off, 42, 0.1)}, options);
  EXPECT_EQ(none.rms_px, none.rms_without_model_px);

  const StabiliserFitResult ois_on = fitStabiliser({observe(knownStabiliser(), 43, 0.1)}, options);
  const NoLensMotionCheck on_check = checkFitAgainstNoLensMotion(
      ois_on.parameters, {observe(knownStabiliser(), 43, 0.1)}, {observe(knownStabiliser(), 44, 0.1)}, options);
  EXPECT_FALSE(on_check.refused) << on_check.reason;
}

TEST(StabiliserFit, RefusesDataWithoutAUsableObservation) {
  StabiliserFitRecording recording = observe(knownStabiliser(), 5, 0.0);
  for (auto& o : recording.observations) o.t_a_s = o.t_b_s = 100.0;  // outside the gyro stream
  EXPECT_THROW(fitStabiliser({recording}, StabiliserFitOptions{}), std::invalid_argument);
  recording.focal_px = 0.0;
  EXPECT_THROW(fitStabiliser({recording}, StabiliserFitOptions{}), std::invalid_argument);
}

// The model read back from its file predicts what the one in memory does.
void expectSamePredictions(const StabiliserModel& in_memory, const StabiliserModel& read_back) {
  LensShiftPredictor a(in_memory, kFocalPx), b(read_back, kFocalPx);
  for (const auto& r : shake(0.0, 2.0, 7)) a.addRate(r), b.addRate(r);
  EXPECT_LT((a.lensShiftAt(1.9) - b.lensShiftAt(1.9)).norm(), 1e-6);
}

// A model file's text that must be refused with an error naming `field`.
void expectRefusedNaming(const std::string& yaml, const std::string& field, const std::string& what) {
  try {
    StabiliserModelFile::fromYaml(yaml);
    ADD_FAILURE() << what;
  } catch (const StabiliserModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(StabiliserModelFile, RoundTripsEveryFieldAndNamesABadOne) {
  StabiliserModelFile file;
  file.name = "test camera";
  file.parameters = knownStabiliser();
  file.parameters.get<PanDetectionValues>().pan_detection_rate_rad_s = 0.6;
  file.parameters.get<StrokeValues>().circular_stroke = true;
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  file.training.target = "gyro-anchored lens shift (images)";
  file.training.data_files = {"a.bag", "b.bag"};
  file.training.observations = 1234;
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(file.toYaml());
  EXPECT_EQ(back.name, file.name);
  EXPECT_TRUE(back.parameters.get<CentringValues>().gain.isApprox(file.parameters.get<CentringValues>().gain));
  EXPECT_DOUBLE_EQ(back.parameters.get<CentringValues>().highpass_corner_hz, 0.8);
  EXPECT_DOUBLE_EQ(back.parameters.get<ActuatorValues>().sensor_lag_s, 0.002);
  EXPECT_TRUE(back.parameters.get<StrokeValues>().circular_stroke);
  EXPECT_DOUBLE_EQ(back.parameters.get<PanDetectionValues>().pan_detection_rate_rad_s, 0.6);
  EXPECT_EQ(back.camera.summary(), file.camera.summary());
  EXPECT_EQ(back.training.data_files, file.training.data_files);
  EXPECT_EQ(back.training.observations, 1234u);

  std::string yaml = file.toYaml();
  yaml.replace(yaml.find("actuator_damping"), 16, "actuator_dumping");
  expectRefusedNaming(yaml, "actuator_damping", "a model without actuator_damping was accepted");
  EXPECT_THROW(StabiliserModelFile::fromYaml("format: something_else\n"), StabiliserModelFileError);
  EXPECT_THROW(StabiliserModelFile::load("/nonexistent/model.yaml"), StabiliserModelFileError);
}

// A mistyped --out folder (train_stabiliser, lens_log_fit, the online learner all save through
// StabiliserModelFile::save): the error names the folder and the system's reason, and the folder
// is not created behind the user's back.
TEST(StabiliserModelFile, SavingWhereTheFolderIsMissingNamesTheFolder) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("deep_ois_model_file_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  StabiliserModelFile file;
  file.name = "test camera";
  file.parameters = knownStabiliser();

  const fs::path missing = dir / "mistyped_folder";
  for (const bool probe_only : {true, false}) {
    try {
      if (probe_only)
        StabiliserModelFile::checkSavable((missing / "model.yaml").string());
      else
        file.save((missing / "model.yaml").string());
      ADD_FAILURE() << "saving into a missing folder was accepted";
    } catch (const StabiliserModelFileError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("the folder " + missing.string() + " does not exist"), std::string::npos)
          << what;
      EXPECT_NE(what.find(std::strerror(ENOENT)), std::string::npos) << "the system's reason: " << what;
    }
    EXPECT_FALSE(fs::exists(missing)) << "the folder was created behind the user's back";
  }

  const fs::path not_a_folder = dir / "a_file";
  std::ofstream(not_a_folder) << "not a folder\n";
  try {
    file.save((not_a_folder / "model.yaml").string());
    ADD_FAILURE() << "saving below a file was accepted";
  } catch (const StabiliserModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find(not_a_folder.string() + " is not a folder"),
              std::string::npos)
        << e.what();
  }

  // Where the folder exists: the probe leaves nothing behind, the model reads back.
  const std::string good = (dir / "model.yaml").string();
  StabiliserModelFile::checkSavable(good);
  file.save(good);
  EXPECT_EQ(StabiliserModelFile::load(good).name, file.name);
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 2u) << "a partial file was left beside the model";
  fs::remove_all(dir);
}

TEST(CameraRateCursor, IsLinearBetweenSamplesAndHeldOutsideThem) {
  const std::vector<CameraRateSample> rates = {{1.0, Eigen::Vector3d(1.0, 0.0, -2.0)},
                                               {1.5, Eigen::Vector3d(3.0, 1.0, -2.0)},
                                               {2.5, Eigen::Vector3d(-1.0, 1.0, 0.0)}};
  CameraRateCursor cursor(rates);
  EXPECT_TRUE(cursor.at(0.2).isApprox(rates[0].rate_rad_s)) << "held before the first sample";
  EXPECT_TRUE(cursor.at(1.0).isApprox(rates[0].rate_rad_s));
  EXPECT_TRUE(cursor.at(1.25).isApprox(Eigen::Vector3d(2.0, 0.5, -2.0)));
  EXPECT_TRUE(cursor.at(1.5).isApprox(rates[1].rate_rad_s));
  EXPECT_TRUE(cursor.at(2.0).isApprox(Eigen::Vector3d(1.0, 1.0, -1.0)));
  EXPECT_TRUE(cursor.at(2.5).isApprox(rates[2].rate_rad_s));
  EXPECT_TRUE(cursor.at(9.0).isApprox(rates[2].rate_rad_s)) << "held after the last sample";
}

TEST(CameraDescription, FrameRateFromStampsIgnoresADroppedFrame) {
  EXPECT_NEAR(frameRateOfStampsHz({0.0, 1.0 / 30, 2.0 / 30, 4.0 / 30, 5.0 / 30}), 30.0, 1e-9);
  EXPECT_EQ(frameRateOfStampsHz({1.0}), 0.0);  // unknown
}

TEST(CameraDescription, SaysHowAnotherCameraDiffers) {
  const CameraDescription trained{360, 270, 257.1, 257.1, 179.5, 134.5, 0.022, 30.0};
  EXPECT_EQ(trained.differencesTo(trained), "");
  const CameraDescription other{640, 480, 554.3, 554.3, 319.5, 239.5, 0.030, 30.0};
  const std::string difference = trained.differencesTo(other);
  EXPECT_NE(difference.find("image size"), std::string::npos) << difference;
  EXPECT_NE(difference.find("focal length"), std::string::npos) << difference;
  EXPECT_NE(difference.find("readout"), std::string::npos) << difference;
  EXPECT_EQ(difference.find("frame rate"), std::string::npos) << difference;
  EXPECT_EQ(trained.differencesTo(CameraDescription{}), "");  // an older model: unknown camera
  // A network's training records carry no readout: not compared, and said to be unknown.
  CameraDescription network = trained;
  network.readout_time_s = CameraDescription::kUnknownReadout;
  network.frame_rate_hz = 0.0;
  EXPECT_EQ(network.differencesTo(other).find("readout"), std::string::npos);
  EXPECT_EQ(network.summary(), "360x270, fx 257.1 fy 257.1 cx 179.5 cy 134.5, readout unknown, frame rate unknown");
}

TEST(StabiliserCompensator, ComposesThePredictedLensShiftsWithTheGyroRotations) {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 180.0, 0.0, kFocalPx, 135.0, 0.0, 0.0, 1.0;
  StabiliserCompensator compensator(knownStabiliser(), K);
  std::vector<Eigen::Matrix3d> rotations(6, Eigen::Matrix3d::Identity());
  std::vector<double> times_a, times_b;
  for (int i = 0; i < 6; ++i) {
    times_a.push_back(1.0 + 0.02 * (i + 0.5) / 6.0);
    times_b.push_back(times_a.back() + 1.0 / 30.0);
  }
  EXPECT_FALSE(compensator.compensate(rotations, times_a, times_b).ok);  // no gyro yet
  EXPECT_DOUBLE_EQ(compensator.feedFrom(times_a.front()), times_a.front() - 1.0);  // warm-up
  compensator.addRates(shake(0.0, 1.2, 3));
  const StabiliserCompensation result = compensator.compensate(rotations, times_a, times_b);
  ASSERT_TRUE(result.ok) << result.reason;
  for (int i = 0; i < 6; ++i) {
    // With R = I the motion is the lens' own: a translation by s_b - s_a.
    const Eigen::Vector2d moved = (result.homographies[i] * Eigen::Vector3d(100.0, 50.0, 1.0)).hnormalized();
    const Eigen::Vector2d expected =
        Eigen::Vector2d(100.0, 50.0) + result.shift_b_px[i] - result.shift_a_px[i];
    EXPECT_LT((moved - expected).norm(), 1e-9);
    EXPECT_LT((result.shift_a_px[i] - compensator.predictor().lensShiftAt(times_a[i])).norm(), 1e-12);
  }
  EXPECT_THROW(lensShiftHomographies(K, rotations, result.shift_a_px, {}), std::invalid_argument);
}


// ---- A linear filter added to the lens (the form older files' residual banks convert to) ----

// The known chain plus a linear-dynamics stage over three first-order low-passes of the rate, added
// to the lens after the chain; `seed` draws its coefficients.
StabiliserModel withLensLinearDynamics(unsigned seed) {
  StabiliserModel p = knownStabiliser();
  LinearDynamicsValues linear;
  linear.output_to_lens = true;
  linear.basis.time_constants_s = {0.03, 0.15, 0.6};
  linear.basis.order = 3;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coefficient(-0.05, 0.05);
  linear.coefficients = Eigen::MatrixXd::NullaryExpr(2, 9, [&]() { return coefficient(rng); });
  p.set(linear);
  return p;
}

TEST(LensLinearDynamics, CarriesItsStateFrameByFrameAndResetsOnAGapOrAJumpBack) {
  const StabiliserModel p = withLensLinearDynamics(3);
  ASSERT_EQ(p.validate(), "");
  const auto rates = shake(10.0, 3.0, 1);
  LensShiftPredictor whole(p, kFocalPx), framewise(p, kFocalPx), physical(knownStabiliser(), kFocalPx);
  for (const auto& r : rates) whole.addRate(r), physical.addRate(r);
  double max_difference = 0.0, linear_part = 0.0;
  std::size_t k = 0;
  for (double frame_end = 10.0; k < rates.size(); frame_end += 1.0 / 30.0) {
    while (k < rates.size() && rates[k].stamp_s <= frame_end) framewise.addRate(rates[k++]);
  }
  for (double t = 12.6; t < 12.95; t += 0.01) {
    max_difference = std::max(max_difference, (framewise.lensShiftAt(t) - whole.lensShiftAt(t)).norm());
    linear_part = std::max(linear_part, (whole.lensShiftAt(t) - physical.lensShiftAt(t)).norm());
  }
  EXPECT_EQ(framewise.resets(), 0);
  EXPECT_LT(max_difference, 1e-12);
  EXPECT_GT(linear_part, 0.01);  // the stage acts (it is not a no-op)

  // A gap: centred lens, filters at rest, as a fresh model.
  CameraRateSample after{whole.newestStamp() + 0.5, Eigen::Vector3d(0.3, -0.2, 0.0)};
  EXPECT_TRUE(whole.addRate(after));
  EXPECT_EQ(whole.resets(), 1);
  EXPECT_NEAR(whole.lensShiftAt(after.stamp_s).norm(), 0.0, 1e-12);
  // Time jumps back (a bag replayed from its start): it starts over from the new sample and then
  // predicts exactly as a fresh model fed the same samples.
  LensShiftPredictor fresh(p, kFocalPx);
  for (const auto& r : rates) {
    if (r.stamp_s > 11.0) break;
    const int before = whole.resets();
    EXPECT_TRUE(whole.addRate(r));
    if (&r == &rates.front()) {
      EXPECT_EQ(whole.resets(), before + 1);
    }
    fresh.addRate(r);
  }
  EXPECT_LT((whole.lensShiftAt(10.95) - fresh.lensShiftAt(10.95)).norm(), 1e-12);
  // A stray sample a little back is ignored, not a reset.
  const int resets = whole.resets();
  EXPECT_FALSE(whole.addRate({whole.newestStamp() - 0.01, Eigen::Vector3d::Zero()}));
  EXPECT_EQ(whole.resets(), resets);
}

TEST(LensLinearDynamics, RoundTripsItsFileAndNamesABadOne) {
  StabiliserModelFile file;
  file.name = "lens linear dynamics";
  file.parameters = withLensLinearDynamics(4);
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  file.training.data_files = {"a.bag"};
  const std::string yaml = file.toYaml();
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(yaml);
  const LinearDynamicsValues& linear = back.parameters.get<LinearDynamicsValues>();
  EXPECT_TRUE(linear.output_to_lens);
  EXPECT_EQ(linear.basis.time_constants_s, file.parameters.get<LinearDynamicsValues>().basis.time_constants_s);
  EXPECT_TRUE(linear.coefficients.isApprox(file.parameters.get<LinearDynamicsValues>().coefficients, 1e-9));
  EXPECT_EQ(back.training.data_files, file.training.data_files);
  // Same predictions from the file as from memory.
  expectSamePredictions(file.parameters, back.parameters);

  std::string bad = yaml;
  bad.replace(bad.find("output: lens"), 12, "output: lends");
  expectRefusedNaming(bad, "linear_dynamics.output", "an unknown output was accepted");
  bad = yaml;
  bad.replace(bad.find("[0.03"), 5, "[-0.03");
  expectRefusedNaming(bad, "time_constants_s", "a negative time constant was accepted");
}

// The chain with its integrator held at the end stop: a stabiliser driven onto its stroke and
// back. The anti-windup lens leaves the stroke as soon as the rate turns; a winding-up one stays
// until the angle it integrated beyond the stroke has come back.
StabiliserModel saturatingStabiliser(bool anti_windup) {
  StabiliserModel p;
  p.get<CentringValues>().highpass_corner_hz = 0.2;
  p.get<ActuatorValues>().actuator_natural_hz = 200.0;
  p.get<ActuatorValues>().actuator_damping = 0.9;
  p.get<StrokeValues>().stroke_x_deg = p.get<StrokeValues>().stroke_y_deg = 0.5;
  p.get<StrokeValues>().circular_stroke = true;
  p.get<StrokeValues>().anti_windup = anti_windup;
  return p;
}

// A turn about y at 0.2 rad/s for 0.2 s (2.3 deg, far past the 0.5 deg stroke), then back at
// -0.2 rad/s for 0.2 s, 400 Hz.
std::vector<CameraRateSample> turnAndBack() {
  std::vector<CameraRateSample> rates;
  for (double t = 0.0; t <= 0.4 + 1e-9; t += 1.0 / 400.0)
    rates.push_back({t, Eigen::Vector3d(0.0, t < 0.2 ? 0.2 : -0.2, 0.0)});
  return rates;
}

TEST(AntiWindup, TheLensLeavesItsStrokeAsSoonAsTheTurnReverses) {
  LensShiftPredictor held(saturatingStabiliser(true), kFocalPx),
      winding(saturatingStabiliser(false), kFocalPx);
  for (const auto& r : turnAndBack()) held.addRate(r), winding.addRate(r);
  const double stroke_px = kFocalPx * std::tan(0.5 * 3.14159265358979 / 180.0);
  // Both sit on the stroke at the end of the turn.
  EXPECT_NEAR(held.lensShiftAt(0.2).x(), stroke_px, 0.02 * stroke_px);
  EXPECT_NEAR(winding.lensShiftAt(0.2).x(), stroke_px, 0.02 * stroke_px);
  // 50 ms into the turn back: the held integrator has come off by about the angle turned back
  // (0.2 rad/s x 50 ms = 0.57 deg, more than the stroke: the lens is near the other side's
  // direction); the winding one still has 1.7 deg beyond the stroke to unwind.
  const double back = kFocalPx * std::tan(0.2 * 0.05);
  EXPECT_NEAR(held.lensShiftAt(0.25).x(), stroke_px - back, 0.1 * stroke_px);
  EXPECT_NEAR(winding.lensShiftAt(0.25).x(), stroke_px, 0.02 * stroke_px);
}

// A structural mechanism's state, fed frame by frame, equals the whole stream's; it acts on a
// stream that reaches the stroke (differs from `without_mechanism`); a gap restarts it from a
// centred lens and a jump back starts it over, exactly as a fresh model.
void expectStateCarriedAndReset(const StabiliserModel& p,
                                const StabiliserModel& without_mechanism) {
  ASSERT_EQ(p.validate(), "");
  const auto rates = shake(10.0, 3.0, 1);  // reaches the 0.5 deg stroke
  LensShiftPredictor whole(p, kFocalPx), framewise(p, kFocalPx), plain(without_mechanism, kFocalPx);
  for (const auto& r : rates) whole.addRate(r), plain.addRate(r);
  std::size_t k = 0;
  for (double frame_end = 10.0; k < rates.size(); frame_end += 1.0 / 30.0)
    while (k < rates.size() && rates[k].stamp_s <= frame_end) framewise.addRate(rates[k++]);
  double max_difference = 0.0, structural_part = 0.0;
  for (double t = 11.0; t < 12.95; t += 0.01) {
    max_difference = std::max(max_difference, (framewise.lensShiftAt(t) - whole.lensShiftAt(t)).norm());
    structural_part = std::max(structural_part, (whole.lensShiftAt(t) - plain.lensShiftAt(t)).norm());
  }
  EXPECT_EQ(framewise.resets(), 0);
  EXPECT_LT(max_difference, 1e-12);
  EXPECT_GT(structural_part, 0.1);  // the mechanism acts on this stream

  // A gap: a centred lens, as a fresh model.
  const CameraRateSample after{whole.newestStamp() + 0.5, Eigen::Vector3d(0.3, -0.2, 0.0)};
  EXPECT_TRUE(whole.addRate(after));
  EXPECT_EQ(whole.resets(), 1);
  EXPECT_NEAR(whole.lensShiftAt(after.stamp_s).norm(), 0.0, 1e-12);
  // Time jumps back: it starts over and predicts exactly as a fresh model fed the same samples.
  LensShiftPredictor fresh(p, kFocalPx);
  for (const auto& r : rates) {
    if (r.stamp_s > 11.5) break;
    EXPECT_TRUE(whole.addRate(r));
    fresh.addRate(r);
  }
  EXPECT_EQ(whole.resets(), 2);
  EXPECT_LT((whole.lensShiftAt(11.45) - fresh.lensShiftAt(11.45)).norm(), 1e-12);
}

TEST(AntiWindup, CarriesItsStateFrameByFrameAndResetsOnAGapOrAJumpBack) {
  StabiliserModel p = saturatingStabiliser(true);
  p.get<ExcursionCentringValues>().excursion_centring = 2.0;
  expectStateCarriedAndReset(p, saturatingStabiliser(false));
}

TEST(AntiWindup, RoundTripsItsFileAndAnOlderFileLoadsWithoutIt) {
  StabiliserModelFile file;
  file.name = "anti-windup";
  file.parameters = saturatingStabiliser(true);
  file.parameters.get<ExcursionCentringValues>().excursion_centring = 1.5;
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(file.toYaml());
  EXPECT_TRUE(back.parameters.get<StrokeValues>().anti_windup);
  EXPECT_DOUBLE_EQ(back.parameters.get<ExcursionCentringValues>().excursion_centring, 1.5);
  expectSamePredictions(file.parameters, back.parameters);
  // A file without the fields (every model before them) is a winding-up fixed-corner chain.
  StabiliserModelFile plain = file;
  plain.parameters = saturatingStabiliser(false);
  const std::string yaml = plain.toYaml();
  EXPECT_EQ(yaml.find("anti_windup"), std::string::npos);
  EXPECT_EQ(yaml.find("excursion_centring"), std::string::npos);
  const StabiliserModelFile old = StabiliserModelFile::fromYaml(yaml);
  EXPECT_FALSE(old.parameters.get<StrokeValues>().anti_windup);
  EXPECT_EQ(old.parameters.get<ExcursionCentringValues>().excursion_centring, 0.0);
  // A negative excursion_centring is named.
  std::string bad = file.toYaml();
  bad.replace(bad.find("excursion_centring: 1.5"), 23, "excursion_centring: -1");
  expectRefusedNaming(bad, "excursion_centring", "a negative excursion_centring was accepted");
}

// The structural-refit tests' common run: two noisy training recordings and one clean held-out one
// of `truth` (seeds first_seed, +1, +2), the chain fitted (without the mechanism: checked by the
// caller on the returned fit), the candidates selected and printed.
struct RefitRun {
  StabiliserFitResult fit;
  StabiliserSelection selection;
  const StabiliserCandidate& kept() const { return selection.candidates[selection.kept]; }
  double chainHeldOutRmsPx() const { return selection.candidates[0].held_out.rms_px; }
};
RefitRun fitAndSelect(const StabiliserModel& truth, unsigned first_seed) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.iterations = 15;
  const std::vector<StabiliserFitRecording> training = {observe(truth, first_seed, 0.02),
                                                        observe(truth, first_seed + 1, 0.02)};
  const std::vector<StabiliserFitRecording> held_out = {observe(truth, first_seed + 2, 0.0)};
  RefitRun run;
  run.fit = fitStabiliser(training, options);
  run.selection = selectStabiliser(run.fit, training, held_out, options);
  for (const auto& c : run.selection.candidates)
    std::printf("[ figures  ] %s: training %.4f px, held out %.4f px\n", c.name.c_str(),
                c.training.rms_px, c.held_out.rms_px);
  std::printf("[ figures  ] %s\n", run.selection.reason.c_str());
  return run;
}

// A stabiliser with an anti-windup integrator that sits on its stroke much of the time: the chain
// refitted with that structure is what the held-out rule keeps, and it is much better than the
// winding-up chain fitted to the same data.
TEST(AntiWindup, IsRefittedAndKeptWhenItPredictsHeldOutDataBetter) {
  StabiliserModel truth = knownStabiliser();
  truth.get<StrokeValues>().stroke_x_deg = truth.get<StrokeValues>().stroke_y_deg = 0.5;
  truth.get<StrokeValues>().circular_stroke = true;
  truth.get<StrokeValues>().anti_windup = true;
  const RefitRun run = fitAndSelect(truth, 41);
  EXPECT_FALSE(run.fit.parameters.get<StrokeValues>().anti_windup);
  EXPECT_TRUE(run.kept().parameters.get<StrokeValues>().anti_windup) << run.kept().name;
  EXPECT_LT(run.kept().held_out.rms_px, 0.5 * run.chainHeldOutRmsPx());
  EXPECT_NEAR(run.kept().parameters.get<StrokeValues>().stroke_x_deg, 0.5, 0.05);
}

// A mount turned against the image with coupled lens axes: the gain maps the camera's angles into
// the actuator's axes, the box stroke holds there, and the image shift is the coupled output.
StabiliserModel coupledStabiliser() {
  StabiliserModel p = saturatingStabiliser(false);
  p.get<StrokeValues>().circular_stroke = false;
  const double turn = 12.0 * 3.14159265358979 / 180.0;
  p.get<CentringValues>().gain = Eigen::Matrix2d(Eigen::Rotation2Dd(turn)) * p.get<CentringValues>().gain;
  p.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, -0.08);
  return p;
}

TEST(ActuatorCoupling, TheLensShiftIsTheCoupledOutputOfTheActuatorsBox) {
  // A turn about y far past the stroke, gain ideal: the actuator sits at (stroke, 0) and the image
  // shift is (stroke, c_yx stroke), outside the image-axes box the chain alone could reach.
  StabiliserModel p = saturatingStabiliser(false);
  p.get<StrokeValues>().circular_stroke = false;
  p.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, -0.08);
  LensShiftPredictor predictor(p, kFocalPx);
  for (const auto& r : turnAndBack()) predictor.addRate(r);
  const double stroke_px = kFocalPx * std::tan(0.5 * 3.14159265358979 / 180.0);
  EXPECT_NEAR(predictor.lensShiftAt(0.2).x(), stroke_px, 0.01 * stroke_px);
  EXPECT_NEAR(predictor.lensShiftAt(0.2).y(), -0.08 * stroke_px, 0.01 * stroke_px);
}

TEST(ActuatorCoupling, CarriesItsStateFrameByFrameAndResetsOnAGapOrAJumpBack) {
  const StabiliserModel p = coupledStabiliser();
  StabiliserModel uncoupled = p;
  uncoupled.get<ActuatorCouplingValues>().actuator_coupling.setZero();
  expectStateCarriedAndReset(p, uncoupled);
}

TEST(ActuatorCoupling, RoundTripsItsFileAndAnOlderFileLoadsWithoutIt) {
  StabiliserModelFile file;
  file.name = "coupled";
  file.parameters = coupledStabiliser();
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(file.toYaml());
  EXPECT_DOUBLE_EQ(back.parameters.get<ActuatorCouplingValues>().actuator_coupling.x(), 0.1);
  EXPECT_DOUBLE_EQ(back.parameters.get<ActuatorCouplingValues>().actuator_coupling.y(), -0.08);
  expectSamePredictions(file.parameters, back.parameters);
  // A file without the field (every model before it) is an uncoupled chain.
  StabiliserModelFile plain = file;
  plain.parameters.get<ActuatorCouplingValues>().actuator_coupling.setZero();
  const std::string yaml = plain.toYaml();
  EXPECT_EQ(yaml.find("actuator_coupling"), std::string::npos);
  EXPECT_TRUE(StabiliserModelFile::fromYaml(yaml).parameters.get<ActuatorCouplingValues>().actuator_coupling.isZero(0.0));
  // A coupling beyond +-0.5 and a wrong count are named.
  for (const char* replacement : {"actuator_coupling: [0.9, 0]", "actuator_coupling: [0.1]"}) {
    std::string bad = file.toYaml();
    const std::size_t at = bad.find("actuator_coupling:");
    ASSERT_NE(at, std::string::npos);
    bad.replace(at, bad.find('\n', at) - at, replacement);
    try {
      StabiliserModelFile::fromYaml(bad);
      FAIL() << replacement << " was accepted";
    } catch (const StabiliserModelFileError& e) {
      EXPECT_NE(std::string(e.what()).find("actuator_coupling"), std::string::npos) << e.what();
    }
  }
}

// A turned, coupled mount whose lens sits on its box stroke much of the time: the chain refitted
// with the stroke in the actuator's axes and the coupling after it is kept by the held-out rule,
// with about the true coupling.
TEST(ActuatorCoupling, IsRefittedAndKeptWhenItPredictsHeldOutDataBetter) {
  StabiliserModel truth = knownStabiliser();  // its 0.8 x 1.2 deg box stroke
  truth.get<CentringValues>().gain = Eigen::Matrix2d(Eigen::Rotation2Dd(12.0 * 3.14159265358979 / 180.0)) * truth.get<CentringValues>().gain;
  truth.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, 0.1);
  const RefitRun run = fitAndSelect(truth, 51);
  EXPECT_TRUE(run.fit.parameters.get<ActuatorCouplingValues>().actuator_coupling.isZero(0.0));
  EXPECT_NEAR(run.kept().parameters.get<ActuatorCouplingValues>().actuator_coupling.x(), 0.1, 0.03) << run.kept().name;
  EXPECT_NEAR(run.kept().parameters.get<ActuatorCouplingValues>().actuator_coupling.y(), 0.1, 0.03) << run.kept().name;
  EXPECT_LT(run.kept().held_out.rms_px, 0.5 * run.chainHeldOutRmsPx());
}

// A soft stroke: the command passes as stroke * tanh(command / stroke), so the lens nears the stroke
// but never stops on it, and halfway to it the lens is already held back (tanh(0.5) = 0.46).
TEST(SoftStroke, CompressesTheCommandTowardsTheStrokeWithoutReachingIt) {
  StabiliserModel hard = saturatingStabiliser(false), soft = hard;
  hard.get<StrokeValues>().circular_stroke = soft.get<StrokeValues>().circular_stroke = false;
  soft.get<StrokeValues>().soft_stroke = true;
  ASSERT_EQ(soft.validate(), "");
  LensShiftPredictor hard_lens(hard, kFocalPx), soft_lens(soft, kFocalPx);
  for (const auto& r : turnAndBack()) hard_lens.addRate(r), soft_lens.addRate(r);
  const double stroke_px = kFocalPx * std::tan(0.5 * 3.14159265358979 / 180.0);
  // 2.3 deg turned against a 0.5 deg stroke: the end stop holds the lens on it, the soft stroke
  // just inside it.
  EXPECT_NEAR(hard_lens.lensShiftAt(0.2).x(), stroke_px, 0.02 * stroke_px);
  EXPECT_LT(soft_lens.lensShiftAt(0.2).x(), stroke_px);
  EXPECT_GT(soft_lens.lensShiftAt(0.2).x(), 0.95 * stroke_px);
  // 0.25 deg turned (21.8 ms at 0.2 rad/s, half the stroke; the actuator at 200 Hz follows within
  // a millisecond): the soft lens has moved about tanh(0.5) / 0.5 = 0.92 of the hard one.
  const double ratio = soft_lens.lensShiftAt(0.0218).x() / hard_lens.lensShiftAt(0.0218).x();
  EXPECT_NEAR(ratio, std::tanh(0.5) / 0.5, 0.03);
}

TEST(SoftStroke, RoundTripsItsFileAndIsRefusedWithAntiWindup) {
  StabiliserModelFile file;
  file.name = "soft stroke";
  file.parameters = saturatingStabiliser(false);
  file.parameters.get<StrokeValues>().soft_stroke = true;
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(file.toYaml());
  EXPECT_TRUE(back.parameters.get<StrokeValues>().soft_stroke);
  expectSamePredictions(file.parameters, back.parameters);
  StabiliserModelFile hard = file;
  hard.parameters.get<StrokeValues>().soft_stroke = false;
  EXPECT_EQ(hard.toYaml().find("soft_stroke"), std::string::npos);  // older files load unchanged
  EXPECT_FALSE(StabiliserModelFile::fromYaml(hard.toYaml()).parameters.get<StrokeValues>().soft_stroke);
  std::string both = file.toYaml();
  both.replace(both.find("soft_stroke: true"), 17, "soft_stroke: true\n  anti_windup: true");
  expectRefusedNaming(both, "soft_stroke, anti_windup", "a soft stroke with anti-windup was accepted");
}

// A stabiliser with a soft stroke driven well into it: the chain refitted with a soft stroke is
// what the held-out rule keeps, much better than the end-stop chain fitted to the same data.
TEST(SoftStroke, IsRefittedAndKeptWhenItPredictsHeldOutDataBetter) {
  StabiliserModel truth = knownStabiliser();
  truth.get<StrokeValues>().stroke_x_deg = truth.get<StrokeValues>().stroke_y_deg = 0.5;
  truth.get<StrokeValues>().soft_stroke = true;
  const RefitRun run = fitAndSelect(truth, 61);
  EXPECT_FALSE(run.fit.parameters.get<StrokeValues>().soft_stroke);
  EXPECT_TRUE(run.kept().parameters.get<StrokeValues>().soft_stroke) << run.kept().name;
  EXPECT_LT(run.kept().held_out.rms_px, 0.5 * run.chainHeldOutRmsPx());
  EXPECT_NEAR(run.kept().parameters.get<StrokeValues>().stroke_x_deg, 0.5, 0.05);
}

// The inference budget: 0.5 ms per frame pair on one core, state updates at the gyro rate
// included. The chain with a linear-dynamics stage of the largest basis a candidate has (16
// functions per axis), fed 30 s of 400 Hz gyro as 900 frames.
TEST(LinearDynamicsModel, StaysFarInsideTheInferenceBudget) {
  StabiliserModel p = knownStabiliser();
  LinearDynamicsValues linear;
  linear.basis.pole_hz = 1.0;
  linear.basis.second_pole_hz = 10.0;
  linear.basis.order = 16;
  linear.coefficients = Eigen::MatrixXd::Constant(2, 48, 1e-3);
  p.set(linear);
  p.get<StrokeValues>().anti_windup = true;  // and the structural variants (an exp and an atan per step at most)
  p.get<ExcursionCentringValues>().excursion_centring = 1.0;
  p.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, 0.1);
  const auto rates = shake(0.0, 30.0, 9);
  LensShiftPredictor predictor(p, kFocalPx);
  const auto start = std::chrono::steady_clock::now();
  double sink = 0.0;
  std::size_t k = 0;
  int frames = 0;
  for (double frame_end = 0.0; k < rates.size(); frame_end += 1.0 / 30.0, ++frames) {
    while (k < rates.size() && rates[k].stamp_s <= frame_end) predictor.addRate(rates[k++]);
    for (int patch = 0; patch < 8; ++patch) sink += predictor.lensShiftAt(frame_end - 0.002 * patch).x();
  }
  const double us_per_frame =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count() / frames;
  std::printf("[ figures  ] linear_dynamics 1+10 Hz x16 model: %.1f us per frame (30 fps, 400 Hz gyro, 8 patches)%s\n",
              us_per_frame, std::isfinite(sink) ? "" : " (non-finite)");
  EXPECT_LT(us_per_frame, 500.0);
}

}  // namespace
}  // namespace deep_ois

namespace deep_ois {
namespace {

// Feeds a compensator the pairs of a 30 fps stream over `rates` as the nodelet does (the
// timeline check, then the rates up to the pair) and returns the last pair's result.
StabiliserCompensation compensatePairs(StabiliserCompensator& compensator,
                                       const std::vector<CameraRateSample>& rates, double first_frame_s,
                                       int pairs, double* time_jump_back_s = nullptr) {
  const std::vector<Eigen::Matrix3d> rotations(6, Eigen::Matrix3d::Identity());
  StabiliserCompensation result;
  for (int k = 0; k < pairs; ++k) {
    std::vector<double> times_a, times_b;
    for (int i = 0; i < 6; ++i) {
      times_a.push_back(first_frame_s + k / 30.0 + 0.02 * (i + 0.5) / 6.0);
      times_b.push_back(times_a.back() + 1.0 / 30.0);
    }
    const double back_s = compensator.followTimeline(times_a.front(), times_b.front());
    if (time_jump_back_s && k == 0) *time_jump_back_s = back_s;
    // The rates the gyro flow message carries: a warm-up second before the pair up to its end.
    std::vector<CameraRateSample> carried;
    for (const CameraRateSample& r : rates) {
      if (r.stamp_s > times_a.front() - kStabiliserWarmUpS && r.stamp_s <= times_b.back() + 0.003) carried.push_back(r);
    }
    compensator.addRates(carried);
    result = compensator.compensate(rotations, times_a, times_b);
  }
  return result;
}

TEST(StabiliserCompensator, TimeGoingBackRestartsTheStateWithNothingOfTheOtherTimeline) {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 180.0, 0.0, kFocalPx, 135.0, 0.0, 0.0, 1.0;
  // Timeline A: 100-104 s. Then time goes back (a bag that loops) to timeline B: 98-100 s,
  // another motion.
  const std::vector<CameraRateSample> a = shake(100.0, 4.0, 7), b = shake(97.0, 3.0, 8);
  StabiliserCompensator looped(knownStabiliser(), K), fresh(knownStabiliser(), K);
  double back_s = 0.0;
  ASSERT_TRUE(compensatePairs(looped, a, 101.5, 60, &back_s).ok);
  EXPECT_EQ(back_s, 0.0);
  EXPECT_EQ(looped.timeJumps(), 0);
  const StabiliserCompensation after_jump = compensatePairs(looped, b, 98.2, 1, &back_s);
  // The last pair of A ended at 101.5 + 60 / 30 = 103.5 s (frame b, first patch).
  EXPECT_NEAR(back_s, 103.5 - 98.2, 1e-6);
  EXPECT_EQ(looped.timeJumps(), 1);
  // Today's regression: the old state ignored the older samples and answered nothing.
  ASSERT_TRUE(after_jump.ok) << after_jump.reason;
  // Exactly what a compensator that never saw timeline A answers.
  const StabiliserCompensation expected = compensatePairs(fresh, b, 98.2, 1);
  ASSERT_TRUE(expected.ok) << expected.reason;
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_LT((after_jump.shift_a_px[i] - expected.shift_a_px[i]).norm(), 1e-12) << "patch " << i;
    EXPECT_LT((after_jump.shift_b_px[i] - expected.shift_b_px[i]).norm(), 1e-12) << "patch " << i;
  }
  // And it goes on along the new timeline without further restarts.
  EXPECT_TRUE(compensatePairs(looped, b, 98.2 + 1.0 / 30.0, 30, &back_s).ok);
  EXPECT_EQ(back_s, 0.0);
  EXPECT_EQ(looped.timeJumps(), 1);
}


// A 30 fps stream of `pairs` pairs over `rates` (camera frame k at first_frame_s + k / 30) made with
// time offset offset_s(k) (IMU time = camera time + offset), fed as the nodelet feeds it. When
// `told`, the compensator is given the calibration shift at each change (what the gyro flow's
// calibration_epoch lets the compensation tell); else it sees only the moved times. Every pair's
// result goes to `results`.
void compensateAcrossCalibration(StabiliserCompensator& compensator, const std::vector<CameraRateSample>& rates,
                                 double first_frame_s, int pairs, const std::function<double(int)>& offset_s,
                                 bool told, std::vector<StabiliserCompensation>& results) {
  const std::vector<Eigen::Matrix3d> rotations(6, Eigen::Matrix3d::Identity());
  for (int k = 0; k < pairs; ++k) {
    std::vector<double> times_a, times_b;
    const double offset = offset_s(k);
    for (int i = 0; i < 6; ++i) {
      times_a.push_back(first_frame_s + k / 30.0 + offset + 0.02 * (i + 0.5) / 6.0);
      times_b.push_back(times_a.back() + 1.0 / 30.0);
    }
    const double shift_s = told && k > 0 ? offset - offset_s(k - 1) : 0.0;
    compensator.followTimeline(times_a.front(), times_b.front(), shift_s);
    std::vector<CameraRateSample> carried;
    for (const CameraRateSample& r : rates) {
      if (r.stamp_s > times_a.front() - kStabiliserWarmUpS && r.stamp_s <= times_b.back() + 0.003) carried.push_back(r);
    }
    compensator.addRates(carried);
    results.push_back(compensator.compensate(rotations, times_a, times_b));
  }
}

// Issue 40 item 2: an applied offset change (up or down) moves the times the model is asked about,
// not time itself: the state is carried across it, and every pair after it answers exactly what a
// model that ran on the gyro stream without interruption answers at the new times.
TEST(StabiliserCompensator, AnAppliedOffsetChangeCarriesTheStateAcrossIt) {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 180.0, 0.0, kFocalPx, 135.0, 0.0, 0.0, 1.0;
  const std::vector<CameraRateSample> rates = shake(99.0, 6.0, 11);
  for (double change_s : {0.001, -0.001, 0.015, -0.015}) {
    SCOPED_TRACE("offset change " + std::to_string(1e3 * change_s) + " ms");
    auto offset = [change_s](int k) { return k < 60 ? 0.004 : 0.004 + change_s; };
    StabiliserCompensator applied(knownStabiliser(), K), uninterrupted(knownStabiliser(), K);
    std::vector<StabiliserCompensation> got, expected;
    compensateAcrossCalibration(applied, rates, 100.5, 90, offset, true, got);
    // The reference is never told of timelines: it follows the gyro stream and answers at the
    // same times.
    const std::vector<Eigen::Matrix3d> rotations(6, Eigen::Matrix3d::Identity());
    for (int k = 0; k < 90; ++k) {
      std::vector<double> times_a, times_b;
      for (int i = 0; i < 6; ++i) {
        times_a.push_back(100.5 + k / 30.0 + offset(k) + 0.02 * (i + 0.5) / 6.0);
        times_b.push_back(times_a.back() + 1.0 / 30.0);
      }
      std::vector<CameraRateSample> carried;
      for (const CameraRateSample& r : rates) {
        if (r.stamp_s > times_a.front() - kStabiliserWarmUpS && r.stamp_s <= times_b.back() + 0.003) carried.push_back(r);
      }
      uninterrupted.addRates(carried);
      expected.push_back(uninterrupted.compensate(rotations, times_a, times_b));
    }
    EXPECT_EQ(applied.timeJumps(), 0);
    EXPECT_EQ(applied.stateResets(), 0);
    EXPECT_EQ(applied.calibrationChanges(), 1);
    EXPECT_EQ(applied.calibrationRestarts(), 0);
    for (int k = 0; k < 90; ++k) {
      ASSERT_TRUE(got[k].ok) << "pair " << k << ": " << got[k].reason;
      ASSERT_TRUE(expected[k].ok) << "pair " << k << ": " << expected[k].reason;
      for (std::size_t i = 0; i < 6; ++i) {
        EXPECT_LT((got[k].shift_a_px[i] - expected[k].shift_a_px[i]).norm(), 1e-12) << "pair " << k << " patch " << i;
        EXPECT_LT((got[k].shift_b_px[i] - expected[k].shift_b_px[i]).norm(), 1e-12) << "pair " << k << " patch " << i;
      }
    }
  }
}

// Without being told (what the compensation did before GyroFlow.calibration_epoch), a decrease
// reads as time going back: the model restarts and its output jumps. This is what the test above
// guards against; it also shows the comparison can fail.
TEST(StabiliserCompensator, AnUntoldOffsetDecreaseReadsAsTimeGoingBack) {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 180.0, 0.0, kFocalPx, 135.0, 0.0, 0.0, 1.0;
  const std::vector<CameraRateSample> rates = shake(99.0, 6.0, 11);
  auto offset = [](int k) { return k < 60 ? 0.004 : 0.004 - 0.015; };
  StabiliserCompensator untold(knownStabiliser(), K), told(knownStabiliser(), K);
  std::vector<StabiliserCompensation> a, b;
  compensateAcrossCalibration(untold, rates, 100.5, 61, offset, false, a);
  compensateAcrossCalibration(told, rates, 100.5, 61, offset, true, b);
  EXPECT_EQ(untold.timeJumps(), 1);
  EXPECT_EQ(told.timeJumps(), 0);
  ASSERT_TRUE(a.back().ok && b.back().ok);
  double largest_px = 0.0;
  for (std::size_t i = 0; i < 6; ++i) largest_px = std::max(largest_px, (a.back().shift_b_px[i] - b.back().shift_b_px[i]).norm());
  EXPECT_GT(largest_px, 1e-3) << "a restart warmed up on 1 s of gyro should differ from the carried state";
}

// A calibration moved back further than the model's retained history (0.5 s) cannot be answered
// from the state: it restarts, counted as a calibration restart, and compensates again at once.
TEST(StabiliserCompensator, AnOffsetMovedBackBeyondTheHistoryRestartsAndSaysWhy) {
  Eigen::Matrix3d K;
  K << kFocalPx, 0.0, 180.0, 0.0, kFocalPx, 135.0, 0.0, 0.0, 1.0;
  const std::vector<CameraRateSample> rates = shake(98.0, 7.0, 12);
  auto offset = [](int k) { return k < 60 ? 0.0 : -0.8; };
  StabiliserCompensator applied(knownStabiliser(), K);
  std::vector<StabiliserCompensation> got;
  compensateAcrossCalibration(applied, rates, 100.5, 70, offset, true, got);
  EXPECT_EQ(applied.timeJumps(), 0);
  EXPECT_EQ(applied.calibrationChanges(), 1);
  EXPECT_EQ(applied.calibrationRestarts(), 1);
  for (int k = 60; k < 70; ++k) EXPECT_TRUE(got[k].ok) << "pair " << k << ": " << got[k].reason;
}
}  // namespace
}  // namespace deep_ois
