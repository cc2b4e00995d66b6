// The learned stabiliser model (core/ois/): its state across frames and gaps, its physics on a
// case with a closed form, the fit recovering a known stabiliser, the model file and the camera
// check, and the compensated homographies.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <cstdio>
#include <random>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"

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

StabiliserParameters knownStabiliser() {
  StabiliserParameters p;
  p.gain << 0.0, 0.9, -1.05, 0.0;
  p.highpass_corner_hz = 0.8;
  p.actuator_natural_hz = 30.0;
  p.actuator_damping = 0.6;
  p.sensor_lag_s = 0.002;
  p.stroke_x_deg = 0.8;
  p.stroke_y_deg = 1.2;
  return p;
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
  StabiliserParameters p;
  p.highpass_corner_hz = 0.0;
  p.actuator_natural_hz = 400.0;
  p.actuator_damping = 1.0;
  p.stroke_x_deg = p.stroke_y_deg = 10.0;
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
StabiliserFitRecording observe(const StabiliserParameters& truth, unsigned seed, double noise_px) {
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
  const StabiliserParameters truth = knownStabiliser();
  const std::vector<StabiliserFitRecording> training = {observe(truth, 11, 0.05),
                                                        observe(truth, 12, 0.05)};
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};  // keep the test short: no pan-detection candidates
  options.try_circular_stroke = false;
  options.iterations = 20;
  const StabiliserFitResult fit = fitStabiliser(training, options);
  std::printf("fit: rms without model %.3f px, physical %.3f px, with residual %.3f px\n",
              fit.rms_without_model_px, fit.rms_physical_px, fit.rms_px);
  EXPECT_GT(fit.rms_without_model_px, 0.5);
  EXPECT_LT(fit.rms_px, 0.1);  // the noise (0.05 px per axis) and little more
  EXPECT_NEAR(fit.parameters.gain(0, 1), 0.9, 0.05);
  EXPECT_NEAR(fit.parameters.gain(1, 0), -1.05, 0.05);
  EXPECT_NEAR(fit.parameters.highpass_corner_hz, 0.8, 0.15);
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
  StabiliserParameters p = knownStabiliser();
  p.gain << 0.0, 6.6, -6.4, 0.0;
  p.stroke_x_deg = 9.8;
  p.sensor_lag_s = 0.0;
  p.actuator_damping = 0.05;
  const StabiliserFitReview review = reviewStabiliserFit(p);
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
StabiliserFitRecording observeWithReadout(const StabiliserParameters& truth, unsigned seed,
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
  const StabiliserParameters truth = knownStabiliser();  // 2 ms sensor lag
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

TEST(StabiliserFit, AFitThatDoesNotBeatNoLensMotionOnHeldOutRecordingsIsRefused) {
  StabiliserFitOptions options;
  options.pan_thresholds_rad_s = {0.0};
  options.try_circular_stroke = false;
  options.iterations = 10;
  StabiliserParameters off = knownStabiliser();
  off.gain.setZero();  // the lens never moves: only the noise of the measurement is left
  const StabiliserFitResult ois_off = fitStabiliser({observe(off, 41, 0.1)}, options);
  const StabiliserScore off_held_out =
      scoreStabiliser(ois_off.parameters, {observe(off, 42, 0.1)}, options);
  const std::string refusal = refusalAgainstNoLensMotion(off_held_out);
  // A lens fitted to noise has no timing to check (it named a 16 ms time offset error).
  EXPECT_TRUE(ois_off.review.timing.empty()) << ois_off.review.timing.front();
  EXPECT_NE(refusal.find("does not beat no lens motion"), std::string::npos)
      << "held out: " << off_held_out.rms_px << " px vs " << off_held_out.rms_without_model_px;
  // No lens motion predicts exactly that.
  const StabiliserScore none = scoreStabiliser(noLensMotion(), {observe(off, 42, 0.1)}, options);
  EXPECT_EQ(none.rms_px, none.rms_without_model_px);

  const StabiliserFitResult ois_on = fitStabiliser({observe(knownStabiliser(), 43, 0.1)}, options);
  const StabiliserScore on_held_out =
      scoreStabiliser(ois_on.parameters, {observe(knownStabiliser(), 44, 0.1)}, options);
  EXPECT_EQ(refusalAgainstNoLensMotion(on_held_out), "")
      << on_held_out.rms_px << " px vs " << on_held_out.rms_without_model_px;
}

TEST(StabiliserFit, RefusesDataWithoutAUsableObservation) {
  StabiliserFitRecording recording = observe(knownStabiliser(), 5, 0.0);
  for (auto& o : recording.observations) o.t_a_s = o.t_b_s = 100.0;  // outside the gyro stream
  EXPECT_THROW(fitStabiliser({recording}, StabiliserFitOptions{}), std::invalid_argument);
  recording.focal_px = 0.0;
  EXPECT_THROW(fitStabiliser({recording}, StabiliserFitOptions{}), std::invalid_argument);
}

TEST(StabiliserModelFile, RoundTripsEveryFieldAndNamesABadOne) {
  StabiliserModelFile file;
  file.name = "test camera";
  file.parameters = knownStabiliser();
  file.parameters.pan_detection_rate_rad_s = 0.6;
  file.parameters.circular_stroke = true;
  file.parameters.residual_time_constants_s = {0.01, 0.1};
  file.parameters.residual = Eigen::MatrixXd::Constant(2, 4, 0.001);
  file.camera = {640, 480, 500.0, 501.0, 319.5, 239.5, 0.03, 30.0};
  file.training.target = "gyro-anchored lens shift (images)";
  file.training.data_files = {"a.bag", "b.bag"};
  file.training.observations = 1234;
  const StabiliserModelFile back = StabiliserModelFile::fromYaml(file.toYaml());
  EXPECT_EQ(back.name, file.name);
  EXPECT_TRUE(back.parameters.gain.isApprox(file.parameters.gain));
  EXPECT_DOUBLE_EQ(back.parameters.highpass_corner_hz, 0.8);
  EXPECT_DOUBLE_EQ(back.parameters.sensor_lag_s, 0.002);
  EXPECT_TRUE(back.parameters.circular_stroke);
  EXPECT_DOUBLE_EQ(back.parameters.pan_detection_rate_rad_s, 0.6);
  EXPECT_TRUE(back.parameters.residual.isApprox(file.parameters.residual));
  EXPECT_EQ(back.camera.summary(), file.camera.summary());
  EXPECT_EQ(back.training.data_files, file.training.data_files);
  EXPECT_EQ(back.training.observations, 1234u);

  std::string yaml = file.toYaml();
  yaml.replace(yaml.find("actuator_damping"), 16, "actuator_dumping");
  try {
    StabiliserModelFile::fromYaml(yaml);
    FAIL() << "a model without actuator_damping was accepted";
  } catch (const StabiliserModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find("actuator_damping"), std::string::npos) << e.what();
  }
  EXPECT_THROW(StabiliserModelFile::fromYaml("format: something_else\n"), StabiliserModelFileError);
  EXPECT_THROW(StabiliserModelFile::load("/nonexistent/model.yaml"), StabiliserModelFileError);
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

}  // namespace
}  // namespace deep_ois
