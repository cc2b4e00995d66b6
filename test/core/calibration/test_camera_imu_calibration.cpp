// The camera-IMU calibration on synthetic tracks: the simulator's camera motion, OIS, rolling
// shutter and IMU model (no rendering) produce exact point tracks and a gyro stream with a known
// time offset, readout, bias and mount; the estimator must find them. Fast: no images.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <chrono>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "deep_ois/core/calibration/calibration_priors.h"
#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/calibration/camera_imu_calibration_stages.h"
#include "deep_ois/core/calibration/camera_imu_coarse_alignment.h"
#include "deep_ois/core/gyro/gyro_orientation_table.h"
#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/sim_camera.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// What a synthetic recording is made of.
struct SyntheticSpec {
  std::uint32_t seed = 3;
  double duration_s = 4.0;
  sim::CameraMotionConfig motion = [] {
    sim::CameraMotionConfig config;
    config.translation_rms_m = 0.0;  // pure rotation: the model is exact
    return config;
  }();
  bool ois = false;
  double readout_time_s = 0.017;
  double time_offset_s = 0.023;
  Eigen::Vector3d bias_rad_s{0.004, -0.003, 0.002};
  Eigen::Matrix3d imu_to_camera_rotation =
      expSO3(Eigen::Vector3d(1.5, -2.0, 1.0) * kDeg) * signedAxisPermutations()[13];
  int tracks_per_pair = 80;
  double track_noise_px = 0.1;
};

struct SyntheticRecording {
  CalibrationData data;
  CameraImuCalibration truth;
};

// Tracks from the simulator's own geometry: a random pixel of frame a, seen at its row's time, is
// cast into the world (40 m away) and projected into frame b with its own row time solved.
SyntheticRecording makeRecording(const SyntheticSpec& spec) {
  sim::SensorConfig sensor;
  sensor.width_px = 320;
  sensor.height_px = 240;
  sensor.readout_time_s = spec.readout_time_s;
  const double start_s = -0.5, end_s = spec.duration_s + 0.5;
  const sim::CameraMotion motion(spec.motion, spec.seed, start_s, end_s);
  sim::OisConfig ois_config;
  ois_config.enabled = spec.ois;
  const CameraModel nominal = sim::nominalCamera(sensor);
  const sim::OisModel ois(ois_config, motion, nominal.K()(0, 0), spec.seed);
  const sim::SimCamera camera(sensor, motion, ois);

  sim::ImuConfig imu;
  imu.imu_to_camera_rotation = spec.imu_to_camera_rotation;
  imu.time_offset_s = spec.time_offset_s;
  imu.gyro_bias_random_walk = 0.0;
  imu.gyro_initial_bias_vector_rad_s = spec.bias_rad_s;
  SyntheticRecording out;
  for (const sim::ImuMeasurement& m : sim::sampleImu(imu, motion, spec.seed, -0.35, spec.duration_s + 0.35)) {
    out.data.gyro.push_back({m.stamp_s, m.angular_velocity_rad_s});
  }
  out.data.camera = nominal;
  const int frames = static_cast<int>(spec.duration_s * sensor.frame_rate_hz) + 1;
  for (int k = 0; k < frames; ++k) out.data.frame_stamps_s.push_back(k / sensor.frame_rate_hz);

  std::mt19937 rng(spec.seed);
  std::uniform_real_distribution<double> u(10.0, sensor.width_px - 11.0), v(10.0, sensor.height_px - 11.0);
  std::normal_distribution<double> noise(0.0, spec.track_noise_px);
  for (int k = 0; k + 1 < frames; ++k) {
    CalibrationPair pair;
    pair.frame_a = k;
    pair.frame_b = k + 1;
    const double stamp_a = out.data.frame_stamps_s[k], stamp_b = out.data.frame_stamps_s[k + 1];
    for (int attempt = 0; attempt < 4 * spec.tracks_per_pair &&
                          static_cast<int>(pair.matches.size()) < spec.tracks_per_pair;
         ++attempt) {
      const Eigen::Vector2d pixel_a(u(rng), v(rng));
      const double t_a = camera.rowTime(stamp_a, pixel_a.y());
      const Eigen::Vector3d X = motion.pose(t_a).centre_world_m + 40.0 * camera.rayDirectionWorld(pixel_a, t_a);
      Eigen::Vector2d pixel_b;
      if (!camera.projectRollingShutter(X, stamp_b, &pixel_b)) continue;
      FeatureMatch match;
      match.point_a_px = cv::Point2f(static_cast<float>(pixel_a.x() + noise(rng)),
                                     static_cast<float>(pixel_a.y() + noise(rng)));
      match.point_b_px = cv::Point2f(static_cast<float>(pixel_b.x() + noise(rng)),
                                     static_cast<float>(pixel_b.y() + noise(rng)));
      pair.matches.push_back(match);
    }
    out.data.pairs.push_back(pair);
  }
  out.truth.time_offset_s = spec.time_offset_s;
  out.truth.readout_time_s = spec.readout_time_s;
  out.truth.gyro_bias_rad_s = spec.bias_rad_s;
  out.truth.imu_to_camera_rotation = spec.imu_to_camera_rotation;
  return out;
}

struct Errors {
  double offset_ms, readout_ms, rotation_deg, bias_rad_s;
};

Errors errorsOf(const CalibrationResult& result, const CameraImuCalibration& truth, const std::string& label) {
  const CameraImuCalibration& c = result.calibration;
  Errors e;
  e.offset_ms = (c.time_offset_s - truth.time_offset_s) * 1e3;
  e.readout_ms = (c.readout_time_s - truth.readout_time_s) * 1e3;
  e.rotation_deg = rotationAngleBetween(c.imu_to_camera_rotation, truth.imu_to_camera_rotation) / kDeg;
  e.bias_rad_s = (c.gyro_bias_rad_s - truth.gyro_bias_rad_s).norm();
  std::cout << "[ measured ] " << label << ": offset error " << e.offset_ms << " ms (sigma "
            << c.time_offset_sigma_s * 1e3 << "), readout error " << e.readout_ms << " ms (sigma "
            << c.readout_time_sigma_s * 1e3 << "), rotation error " << e.rotation_deg << " deg, bias error "
            << e.bias_rad_s << " rad/s; " << result.pairs_used << " pairs, " << result.tracks_used
            << " tracks, " << result.iterations << " iterations, median residual " << result.median_residual_px
            << " px, " << result.seconds << " s" << (result.ok() ? "" : "; refused: " + result.reason()) << "\n";
  return e;
}

TEST(SignedAxisPermutations, AreTheTwentyFourDistinctMounts) {
  const std::vector<Eigen::Matrix3d>& all = signedAxisPermutations();
  ASSERT_EQ(all.size(), 24u);
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_TRUE(isProperRotation(all[i])) << i;
    for (std::size_t j = 0; j < i; ++j) EXPECT_GT((all[i] - all[j]).norm(), 1.0) << i << " vs " << j;
    // A mount a few degrees off its axes is still named by its permutation.
    EXPECT_EQ(nearestSignedAxisPermutation(expSO3(Eigen::Vector3d(4.0, -3.0, 5.0) * kDeg) * all[i]),
              static_cast<int>(i));
  }
  Eigen::Matrix3d phone;
  phone << 0, 1, 0, 1, 0, 0, 0, 0, -1;  // the simulator's default mount
  EXPECT_TRUE(all[nearestSignedAxisPermutation(phone)].isApprox(phone));
}

TEST(Kabsch, RecoversARotationFromRotatedVectors) {
  const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(0.3, -1.2, 0.7));
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  const Eigen::Vector3d a[] = {{1, 0, 0}, {0, 1, 0}, {0.3, 0.2, 1.0}};
  for (const Eigen::Vector3d& v : a) M += (R * v) * v.transpose();
  EXPECT_MATRIX_NEAR(R, kabsch(M), 1e-12);
}

TEST(GyroOrientationTable, MatchesDirectIntegration) {
  const ImuSampleBuffer buffer = test::sampledBuffer(0.0, 1.0, 400.0, [](double t) {
    return Eigen::Vector3d(0.3 * std::sin(7.0 * t), -0.2 + 0.4 * t, 0.5 * std::cos(11.0 * t));
  });
  for (RateInterpolation interpolation : {RateInterpolation::kLinear, RateInterpolation::kZeroOrderHold}) {
    IntegrationOptions options;
    options.interpolation = interpolation;
    options.gyro_bias_rad_s = Eigen::Vector3d(0.01, -0.02, 0.005);
    const GyroOrientationTable table(buffer, options);
    for (double t0 : {0.0, 0.1234, 0.5}) {
      for (double t1 : {0.1234, 0.3301, 0.99}) {
        const IntegrationResult direct = integrateRotation(buffer, t0, t1, options);
        ASSERT_TRUE(direct.ok());
        EXPECT_MATRIX_NEAR(direct.rotation, table.relativeRotation(t0, t1), 1e-12);
      }
    }
    EXPECT_TRUE(table.coverage(0.2, 0.8).ok());
    EXPECT_FALSE(table.coverage(0.2, 1.2).ok());
  }
}

// The global stage alone, once per mount: the gyro of an IMU mounted as each of the 24 signed
// axis permutations (plus a few degrees) against exact camera rotations of the frame pairs.
TEST(CoarseAlignment, FindsEveryOneOfTheTwentyFourMountsAndTheOffset) {
  sim::CameraMotionConfig motion_config;
  motion_config.translation_rms_m = 0.0;
  const double duration_s = 3.0, readout_s = 0.02, offset_s = -0.037;
  const sim::CameraMotion motion(motion_config, 5, -0.5, duration_s + 0.5);
  std::vector<CoarsePair> pairs;
  for (int k = 0; k + 1 < 90; ++k) {
    CoarsePair pair;
    pair.stamp_a_s = k / 30.0;
    pair.stamp_b_s = (k + 1) / 30.0;
    pair.mean_row_fraction = 0.5;
    const double t_a = pair.stamp_a_s + 0.5 * readout_s, t_b = pair.stamp_b_s + 0.5 * readout_s;
    const Eigen::Matrix3d R_b_a = motion.pose(t_b).R_world_cam.transpose() * motion.pose(t_a).R_world_cam;
    pair.image_rotation_rad = logSO3(R_b_a);
    pairs.push_back(pair);
  }
  CoarseAlignmentOptions options;
  options.readout_time_s = readout_s;
  for (int p = 0; p < 24; ++p) {
    sim::ImuConfig imu;
    imu.imu_to_camera_rotation = expSO3(Eigen::Vector3d(2.0, 1.0, -3.0) * kDeg) * signedAxisPermutations()[p];
    imu.time_offset_s = offset_s;
    ImuSampleBuffer buffer(100.0);
    for (const sim::ImuMeasurement& m : sim::sampleImu(imu, motion, 17, -0.45, duration_s + 0.45)) {
      buffer.add({m.stamp_s, m.angular_velocity_rad_s});
    }
    const CoarseAlignment coarse = coarseCameraImuAlignment(GyroOrientationTable(buffer, {}), pairs, options);
    EXPECT_EQ(coarse.permutation_index, p);
    EXPECT_NEAR(coarse.time_offset_s, offset_s, 0.001) << "mount " << p;
    EXPECT_LT(rotationAngleBetween(coarse.imu_to_camera_rotation, imu.imu_to_camera_rotation), 0.5 * kDeg)
        << "mount " << p;
    // The next best mount is clearly worse: the search is not a coin toss.
    std::vector<double> costs = coarse.cost_by_permutation;
    std::sort(costs.begin(), costs.end());
    EXPECT_GT(costs[1], 2.0 * costs[0] + 10.0) << "mount " << p;
  }
}

TEST(CameraImuCalibration, RecoversOffsetReadoutBiasAndMountWithoutOis) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  const Errors e = errorsOf(result, recording.truth, "fixed lens, synthetic tracks");
  ASSERT_TRUE(result.ok()) << result.reason();
  EXPECT_EQ(result.coarse_permutation_index, 13);
  EXPECT_LT(std::abs(e.offset_ms), 0.1);
  EXPECT_LT(std::abs(e.readout_ms), 0.2);
  // A misalignment and a bias look alike while the rate stays on one side (slow pans): 4 s of
  // 80 tracks per pair leave ~0.09 degree and ~3e-4 rad/s of 1-sigma uncertainty.
  EXPECT_LT(e.rotation_deg, 0.3);
  EXPECT_LT(e.bias_rad_s, 1e-3);
  // The uncertainty is honest here (the model is exact): the errors are within a few sigma.
  EXPECT_LT(std::abs(e.offset_ms), 4.0 * result.calibration.time_offset_sigma_s * 1e3);
  EXPECT_LT(std::abs(e.readout_ms), 4.0 * result.calibration.readout_time_sigma_s * 1e3);
  EXPECT_LT(result.median_residual_px, 0.2);
}

// The reported 1-sigma is the statistical one inflated, with the systematic term every recording
// shares added in quadrature (docs/calibration_uncertainty.md: that is what covers the benchmark's
// errors); refusals judge the statistical part alone, so even a huge systematic term refuses
// nothing, and factor 1 with no systematic term reports the statistical sigma itself.
TEST(CameraImuCalibration, ReportedSigmaIsTheInflatedStatisticalOnePlusTheSystematicTerm) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  const CalibrationOptions defaults;
  const CalibrationResult result = calibrateCameraImu(recording.data, defaults);
  ASSERT_TRUE(result.ok()) << result.reason();
  const CameraImuCalibration& c = result.calibration;
  const CalibrationResult::Sigmas& statistical = result.statistical;
  ASSERT_GT(statistical.time_offset_s, 0.0);
  const double k = defaults.statistical_sigma_factor;
  EXPECT_GT(k, 1.0);
  EXPECT_NEAR(c.time_offset_sigma_s, std::hypot(k * statistical.time_offset_s, defaults.systematic_time_offset_s), 1e-12);
  EXPECT_NEAR(c.readout_time_sigma_s, std::hypot(k * statistical.readout_time_s, defaults.systematic_readout_time_s),
              1e-12);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(c.rotation_sigma_rad(i), std::hypot(k * statistical.rotation_rad(i), defaults.systematic_rotation_rad),
                1e-12);
    EXPECT_NEAR(c.gyro_bias_sigma_rad_s(i),
                std::hypot(k * statistical.gyro_bias_rad_s(i), defaults.systematic_gyro_bias_rad_s), 1e-12);
  }

  CalibrationOptions statistical_only;
  statistical_only.statistical_sigma_factor = 1.0;
  statistical_only.systematic_time_offset_s = 0.0;
  statistical_only.systematic_readout_time_s = 0.0;
  statistical_only.systematic_rotation_rad = 0.0;
  statistical_only.systematic_gyro_bias_rad_s = 0.0;
  const CalibrationResult bare = calibrateCameraImu(recording.data, statistical_only);
  EXPECT_EQ(bare.calibration.time_offset_s, c.time_offset_s) << "the sigma must not change the estimate";
  EXPECT_DOUBLE_EQ(bare.calibration.time_offset_sigma_s, statistical.time_offset_s);
  EXPECT_DOUBLE_EQ(bare.calibration.readout_time_sigma_s, statistical.readout_time_s);
  EXPECT_TRUE(bare.calibration.rotation_sigma_rad.isApprox(statistical.rotation_rad));

  CalibrationOptions huge_systematic;
  huge_systematic.systematic_rotation_rad = 5.0 * kDeg;
  huge_systematic.systematic_time_offset_s = 0.01;
  const CalibrationResult wide = calibrateCameraImu(recording.data, huge_systematic);
  EXPECT_TRUE(wide.ok()) << "a systematic term no recording can lower must not refuse it: " << wide.reason();
  EXPECT_GT(wide.calibration.rotation_sigma_rad.minCoeff(), 5.0 * kDeg);

  CalibrationOptions bad;
  bad.systematic_readout_time_s = -1e-4;
  EXPECT_NE(bad.validate().find("systematic"), std::string::npos);
  bad = CalibrationOptions();
  bad.statistical_sigma_factor = 0.5;
  EXPECT_NE(bad.validate().find("statistical_sigma_factor"), std::string::npos);
}

// A global-shutter camera 48 ms ahead of its IMU, with a tilted mount.
SyntheticRecording globalShutterRecording() {
  SyntheticSpec spec;
  spec.seed = 8;
  spec.time_offset_s = -0.048;
  spec.readout_time_s = 0.0;
  spec.imu_to_camera_rotation = expSO3(Eigen::Vector3d(-3.0, 0.5, 2.0) * kDeg) * signedAxisPermutations()[4];
  return makeRecording(spec);
}

TEST(CameraImuCalibration, NegativeOffsetAndGlobalShutter) {
  const SyntheticRecording recording = globalShutterRecording();
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  const Errors e = errorsOf(result, recording.truth, "global shutter, -48 ms");
  ASSERT_TRUE(result.ok()) << result.reason();
  // Within ~3 sigma of 80 tracks per pair with 0.1 px noise (the parallax removal keeps one
  // component of each).
  EXPECT_LT(std::abs(e.offset_ms), 0.2);
  EXPECT_LT(std::abs(e.readout_ms), 0.3);
  EXPECT_LT(e.rotation_deg, 0.3);
}

// A readout estimated at its lower bound (a global shutter): the Gaussian interval is wrong there,
// so the intervals must also hold the answer with the readout held at 0.
TEST(CameraImuCalibration, AReadoutAtItsBoundWidensTheIntervalsToHoldTheGlobalShutterAnswer) {
  const SyntheticRecording recording = globalShutterRecording();
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  ASSERT_TRUE(result.ok()) << result.reason();
  // (Other notes, e.g. on the mount being off the camera's axes, may accompany it.)
  auto boundNotes = [](const CalibrationResult& r) {
    return std::count_if(r.notes.begin(), r.notes.end(),
                         [](const std::string& note) { return note.find("at its lower bound") != std::string::npos; });
  };
  ASSERT_EQ(boundNotes(result), 1) << "no note on the readout bound";
  CalibrationOptions held;
  held.estimate_readout_time = false;
  held.readout_time_s = 0.0;
  const CalibrationResult global = calibrateCameraImu(recording.data, held);
  ASSERT_TRUE(global.ok()) << global.reason();
  const CameraImuCalibration& c = result.calibration;
  EXPECT_EQ(boundNotes(global), 0);
  // The reported intervals reach the other answer.
  EXPECT_GE(c.time_offset_sigma_s + 1e-12,
            std::abs(c.time_offset_s - global.calibration.time_offset_s));
  EXPECT_GE(c.readout_time_sigma_s + 1e-12, c.readout_time_s);
  // Switched off, the interval is the usual one (narrower or equal).
  CalibrationOptions usual;
  usual.readout_boundary_s = 0.0;
  const CalibrationResult plain = calibrateCameraImu(recording.data, usual);
  EXPECT_EQ(boundNotes(plain), 0);
  EXPECT_LE(plain.calibration.time_offset_sigma_s, c.time_offset_sigma_s + 1e-12);
}

// OIS: the lens cancels most pan/tilt shake. Estimating each frame's lens shift keeps the
// calibration; ignoring it costs milliseconds and degrees.
TEST(CameraImuCalibration, PerFrameLensShiftKeepsOisCamerasAccurate) {
  SyntheticSpec spec;
  spec.ois = true;
  spec.seed = 21;
  spec.duration_s = 5.0;
  spec.tracks_per_pair = 150;
  spec.track_noise_px = 0.04;  // KLT on the simulator's frames: median endpoint error 0.05 px
  const SyntheticRecording recording = makeRecording(spec);
  CalibrationOptions naive;
  naive.max_iterations = 15;  // it only has to show the bias
  const Errors plain = errorsOf(calibrateCameraImu(recording.data, naive), recording.truth, "OIS, no lens model");
  CalibrationOptions options;
  options.lens_shift = LensShiftHandling::kPerFrameShift;
  const CalibrationResult result = calibrateCameraImu(recording.data, options);
  const Errors e = errorsOf(result, recording.truth, "OIS, per-frame lens shift");
  ASSERT_TRUE(result.ok()) << result.reason();
  EXPECT_LT(std::abs(e.offset_ms), 0.5);
  EXPECT_LT(std::abs(e.readout_ms), 0.5);
  EXPECT_LT(e.rotation_deg, 0.5);
  // The lens shift biases a fit that ignores it.
  EXPECT_GT(std::abs(plain.offset_ms) + std::abs(plain.readout_ms) + plain.rotation_deg,
            std::abs(e.offset_ms) + std::abs(e.readout_ms) + e.rotation_deg);
}

TEST(CameraImuCalibration, HeldQuantitiesStayPut) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  CalibrationOptions options;
  options.estimate_readout_time = false;
  options.readout_time_s = recording.truth.readout_time_s;
  options.estimate_rotation = false;
  options.imu_to_camera_rotation = recording.truth.imu_to_camera_rotation;
  const CalibrationResult result = calibrateCameraImu(recording.data, options);
  ASSERT_TRUE(result.ok()) << result.reason();
  EXPECT_EQ(result.calibration.readout_time_s, recording.truth.readout_time_s);
  EXPECT_TRUE(result.calibration.imu_to_camera_rotation.isApprox(recording.truth.imu_to_camera_rotation));
  EXPECT_EQ(result.coarse_permutation_index, -1);
  EXPECT_NEAR(result.calibration.time_offset_s, recording.truth.time_offset_s, 1e-4);
}

TEST(CameraImuCalibration, RefusesWhenTheCameraDoesNotMove) {
  SyntheticSpec spec;
  spec.motion.shake_rms_rad_s.setZero();
  spec.motion.pan_peak_rad_s = 0.0;
  const SyntheticRecording recording = makeRecording(spec);
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.reason().find("hardly rotates"), std::string::npos) << result.reason();
}

// Nearly still (issue 14: a recording with 0.019 deg between frames was accepted at 2 ms off): a
// slow drift of 0.03 rad/s passes the gyro-rate check, but between frames the image turns by
// ~0.2 px, no more than track noise and parallax. Refused, saying how much rotation is needed.
TEST(CameraImuCalibration, RefusesANearlyStillRecording) {
  SyntheticSpec spec;
  spec.motion.shake_rms_rad_s = Eigen::Vector3d(0.03, 0.03, 0.02);
  spec.motion.shake_peak_rad_s = 0.08;
  spec.motion.pan_peak_rad_s = 0.0;
  spec.motion.translation_rms_m = 0.01;  // a hand or a robot: parallax of a similar size
  spec.readout_time_s = 0.0;             // global shutter, IMU in sync: the truth is 0 / 0
  spec.time_offset_s = 0.0;
  const SyntheticRecording recording = makeRecording(spec);
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  std::printf("[ figures  ] nearly still: gyro RMS %.3f %.3f %.3f rad/s, median image rotation %.2f px\n",
              result.rate_rms_rad_s(0), result.rate_rms_rad_s(1), result.rate_rms_rad_s(2),
              result.median_image_rotation_px);
  EXPECT_GE(result.rate_rms_rad_s(0), CalibrationOptions().min_excitation_rate_rad_s) << "passes the rate check";
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.reason().find("motion: the camera hardly rotates between frames"), std::string::npos)
      << result.reason();
  EXPECT_NE(result.reason().find("at least 0.50 px"), std::string::npos) << result.reason();
}

TEST(CameraImuCalibration, RefusesTheRotationWhenOnlyOneAxisMoves) {
  SyntheticSpec spec;
  spec.motion.shake_rms_rad_s = Eigen::Vector3d(0.0, 0.25, 0.0);  // pan shake only
  spec.motion.pan_peak_rad_s = 0.0;
  const SyntheticRecording recording = makeRecording(spec);
  const CalibrationResult result = calibrateCameraImu(recording.data, CalibrationOptions());
  errorsOf(result, recording.truth, "pan only");
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.reason().find("IMU-camera rotation: the gyro shows rotation about one axis only"),
            std::string::npos)
      << result.reason();
  // Held at its true value, the rotation is no longer needed: the rest is observable.
  CalibrationOptions held;
  held.estimate_rotation = false;
  held.imu_to_camera_rotation = recording.truth.imu_to_camera_rotation;
  const CalibrationResult with_rotation = calibrateCameraImu(recording.data, held);
  const Errors e = errorsOf(with_rotation, recording.truth, "pan only, rotation held");
  EXPECT_TRUE(with_rotation.ok()) << with_rotation.reason();
  EXPECT_LT(std::abs(e.offset_ms), 0.2);
}

TEST(CameraImuCalibration, BadInputIsNamed) {
  SyntheticSpec spec;
  spec.duration_s = 1.0;
  SyntheticRecording recording = makeRecording(spec);
  CalibrationData data = recording.data;
  data.pairs[3].frame_b = 1000;
  try {
    calibrateCameraImu(data, CalibrationOptions());
    FAIL() << "a pair naming a missing frame must be rejected";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pair 3 names frames 3 -> 1000"), std::string::npos) << e.what();
  }
  data = recording.data;
  data.pairs.resize(5);
  try {
    calibrateCameraImu(data, CalibrationOptions());
    FAIL() << "five pairs are too few";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 20 such pairs are needed"), std::string::npos) << e.what();
  }
  CalibrationOptions options;
  options.estimate_readout_time = false;  // held, but no value given
  try {
    calibrateCameraImu(recording.data, options);
    FAIL() << "a held readout needs its value";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("readout_time_s must be in [0, 1] s when the readout is held"),
              std::string::npos)
        << e.what();
  }
}

// ---- The stages alone. -------------------------------------------------------------------------

// The prerequisites stage on its own: a gyro turning about one axis passes the "anything moves"
// checks but not the mount's, a still one passes neither.
TEST(CalibrationStages, MotionPrerequisitesNameWhatIsMissing) {
  CalibrationData data;
  data.camera = sim::nominalCamera(sim::SensorConfig());
  for (int k = 0; k <= 60; ++k) data.frame_stamps_s.push_back(k / 30.0);
  for (int k = -50; k <= 2500; ++k) {
    const double t = k * 0.001;
    data.gyro.push_back({t, Eigen::Vector3d(0.0, 0.3 * std::sin(2.0 * kPi * 2.0 * t), 0.0)});
  }
  const double focal_px = data.camera.K()(0, 0);
  std::vector<CoarsePair> pairs(60);
  for (std::size_t k = 0; k < pairs.size(); ++k) pairs[k].image_rotation_rad = Eigen::Vector3d(0.0, 0.005, 0.0);
  const CalibrationState start;
  const MotionCheck one_axis = checkMotionPrerequisites(data, pairs, start, CalibrationOptions(), 0.03, focal_px);
  EXPECT_TRUE(one_axis.unobservable.empty()) << one_axis.unobservable;
  EXPECT_NE(one_axis.rotation_unobservable.find("about one axis only"), std::string::npos);
  EXPECT_NEAR(one_axis.median_image_rotation_px, 0.005 * focal_px, 1e-9);
  CalibrationOptions mount_held;
  mount_held.estimate_rotation = false;
  EXPECT_TRUE(checkMotionPrerequisites(data, pairs, start, mount_held, 0.03, focal_px).rotation_unobservable.empty());

  for (ImuSample& sample : data.gyro) sample.angular_velocity_rad_s.setZero();
  const MotionCheck still = checkMotionPrerequisites(data, pairs, start, CalibrationOptions(), 0.03, focal_px);
  EXPECT_NE(still.unobservable.find("the camera hardly rotates"), std::string::npos) << still.unobservable;
}

// The refinement and uncertainty stages on their own: from a start 3 ms and a degree off, the
// refinement converges to the truth and does not move what is held; the uncertainty of a held
// parameter is zero (no held 1-sigma given) and that of an estimated one is not.
TEST(CalibrationStages, RefinementConvergesAndHoldsWhatIsHeld) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  const CameraImuCalibration& truth = recording.truth;
  CalibrationOptions options;
  options.estimate_readout_time = false;
  options.readout_time_s = truth.readout_time_s;
  const std::vector<PreparedPair> pairs = preparePairs(recording.data, options.min_tracks_per_pair);
  const ImuSampleBuffer gyro = bufferOf(recording.data.gyro);
  ReprojectionProblem problem(pairs, gyro, recording.data.camera.K(), options.interpolation, options.max_imu_gap_s,
                              options.lens_shift, options.lens_shift_row_order, removesParallax(options));
  CalibrationState state;
  state.time_offset_s = truth.time_offset_s + 3e-3;
  state.readout_time_s = truth.readout_time_s;
  state.R_cam_imu = expSO3(Eigen::Vector3d(1.0, 0.0, 0.0) * kDeg) * truth.imu_to_camera_rotation;
  const ActiveParameters active = activeParameters(options);
  const Refinement refinement = refineCalibration(problem, active, options, 1.0 / 30.0, state);
  EXPECT_TRUE(refinement.converged);
  EXPECT_EQ(refinement.weights.size(), problem.trackCount());
  EXPECT_NEAR(state.time_offset_s, truth.time_offset_s, 0.2e-3);
  EXPECT_EQ(state.readout_time_s, truth.readout_time_s);
  EXPECT_LT(rotationAngleBetween(state.R_cam_imu, truth.imu_to_camera_rotation), 0.3 * kDeg);
  EXPECT_LT((state.bias - truth.gyro_bias_rad_s).norm(), 1e-3);

  const CalibrationUncertainty uncertainty = estimateUncertainty(problem, state, refinement.weights, active, options);
  EXPECT_LT(uncertainty.median_residual_px, 0.2);
  EXPECT_LT(uncertainty.median_residual_px, refinement.initial_median_residual_px);
  EXPECT_EQ(uncertainty.statistical(calibration_parameter::kReadout), 0.0);
  EXPECT_EQ(uncertainty.reported(calibration_parameter::kReadout), 0.0);
  EXPECT_GT(uncertainty.statistical(calibration_parameter::kOffset), 0.0);
  EXPECT_GT(uncertainty.reported(calibration_parameter::kOffset),
            options.statistical_sigma_factor * uncertainty.statistical(calibration_parameter::kOffset));
}

// A held value known to +-s (a logged readout) moves the estimated ones: the reported 1-sigma of
// the time offset takes in (d offset / d readout) s, which a second calibration with the readout
// held 1 ms further measures directly. The statistical sigma (what the refusals judge) is unchanged.
TEST(CalibrationStages, AHeldValuesSigmaReachesTheEstimatedOnes) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  CalibrationOptions exact;
  exact.estimate_readout_time = false;
  exact.readout_time_s = recording.truth.readout_time_s;
  CalibrationOptions uncertain = exact;
  uncertain.held_readout_time_sigma_s = 1e-3;
  CalibrationOptions shifted = exact;
  shifted.readout_time_s += 1e-3;
  const CalibrationResult at_exact = calibrateCameraImu(recording.data, exact);
  const CalibrationResult at_uncertain = calibrateCameraImu(recording.data, uncertain);
  const CalibrationResult at_shifted = calibrateCameraImu(recording.data, shifted);
  ASSERT_TRUE(at_exact.ok() && at_uncertain.ok() && at_shifted.ok());
  const double moved_s = std::abs(at_shifted.calibration.time_offset_s - at_exact.calibration.time_offset_s);
  const double added_s = std::sqrt(std::pow(at_uncertain.calibration.time_offset_sigma_s, 2) -
                                   std::pow(at_exact.calibration.time_offset_sigma_s, 2));
  std::printf("[ figures  ] offset moved %.4f ms by a 1 ms readout step; the held readout's 1 ms adds %.4f ms\n",
              moved_s * 1e3, added_s * 1e3);
  EXPECT_GT(moved_s, 0.1e-3) << "the offset must depend on the readout for this test to mean anything";
  EXPECT_NEAR(added_s, moved_s, 0.2 * moved_s);
  EXPECT_DOUBLE_EQ(at_uncertain.statistical.time_offset_s, at_exact.statistical.time_offset_s);
  EXPECT_DOUBLE_EQ(at_uncertain.calibration.readout_time_sigma_s, 1e-3);
  EXPECT_EQ(at_exact.calibration.readout_time_sigma_s, 0.0);
}

// ---- Priors: what the recording states (calibration_priors.h). -------------------------------

// Pan only: the mount is unobservable and refused on its own. With the stated axis permutation
// (the metadata's, without the true mount's few degrees) the mount is held, with the prior's
// 1-sigma, and the rest comes from the data.
TEST(CalibrationPriors, OneAxisMotionHoldsTheStatedMountAndEstimatesTheRest) {
  SyntheticSpec spec;
  spec.motion.shake_rms_rad_s = Eigen::Vector3d(0.0, 0.25, 0.0);
  spec.motion.pan_peak_rad_s = 0.0;
  spec.imu_to_camera_rotation = expSO3(Eigen::Vector3d(0.3, -0.2, 0.2) * kDeg) * signedAxisPermutations()[13];
  const SyntheticRecording recording = makeRecording(spec);
  ASSERT_FALSE(calibrateCameraImu(recording.data, CalibrationOptions()).ok());

  CalibrationPriors priors;
  priors.source = "test.gyro_flow.yaml";
  priors.imu_to_camera_rotation = signedAxisPermutations()[13];
  const PriorCalibration calibration = calibrateWithPriors(recording.data, CalibrationOptions(), priors);
  const Errors e = errorsOf(calibration.result, recording.truth, "pan only, mount prior");
  for (const std::string& decision : calibration.decisions) std::printf("[ decision ] %s\n", decision.c_str());
  ASSERT_TRUE(calibration.result.ok()) << calibration.result.reason();
  EXPECT_TRUE(calibration.refused_when_free.rotation);
  EXPECT_EQ(calibration.rotation, CalibrationValueSource::kPrior);
  EXPECT_EQ(calibration.time_offset, CalibrationValueSource::kData);
  EXPECT_EQ(calibration.readout_time, CalibrationValueSource::kData);
  EXPECT_EQ(calibration.gyro_bias, CalibrationValueSource::kData);
  EXPECT_TRUE(calibration.result.calibration.imu_to_camera_rotation.isApprox(signedAxisPermutations()[13]));
  EXPECT_DOUBLE_EQ(calibration.result.calibration.rotation_sigma_rad.maxCoeff(), priors.rotation_sigma_rad);
  EXPECT_LT(std::abs(e.offset_ms), 0.5);
  ASSERT_FALSE(calibration.decisions.empty());
  EXPECT_NE(calibration.decisions[0].find("from test.gyro_flow.yaml"), std::string::npos) << calibration.decisions[0];
  EXPECT_NE(calibration.decisions[0].find("about one axis only"), std::string::npos) << calibration.decisions[0];
}

// A mount the motion contradicts (the stated permutation is not the one the data's search picks)
// is not quietly held: refused, naming both.
TEST(CalibrationPriors, AStatedMountTheMotionContradictsIsNotHeld) {
  SyntheticSpec spec;
  spec.motion.shake_rms_rad_s = Eigen::Vector3d(0.0, 0.25, 0.0);
  spec.motion.pan_peak_rad_s = 0.0;
  const SyntheticRecording recording = makeRecording(spec);
  // A stated mount that puts the panning IMU axis on another camera axis than the truth's.
  std::size_t wrong = 0;
  while ((signedAxisPermutations()[wrong].row(1) - signedAxisPermutations()[13].row(1)).norm() < 0.5) ++wrong;
  CalibrationPriors priors;
  priors.imu_to_camera_rotation = signedAxisPermutations()[wrong];
  const PriorCalibration calibration = calibrateWithPriors(recording.data, CalibrationOptions(), priors);
  ASSERT_FALSE(calibration.result.ok());
  EXPECT_EQ(calibration.rotation, CalibrationValueSource::kData);
  ASSERT_EQ(calibration.decisions.size(), 1u);
  EXPECT_NE(calibration.decisions[0].find("the recording's axis search picks"), std::string::npos)
      << calibration.decisions[0];
  EXPECT_NE(calibration.decisions[0].find("the stated mount fits worse"), std::string::npos)
      << calibration.decisions[0];
}

// Everything observable: the priors change nothing but the readout's starting point; a stated
// readout 4 ms off is estimated, not held, and the disagreement is said.
TEST(CalibrationPriors, WhatTheDataDeterminesIsEstimatedAndADisagreementIsSaid) {
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  CalibrationPriors priors;
  priors.readout_time_s = recording.truth.readout_time_s + 4e-3;
  priors.imu_to_camera_rotation = signedAxisPermutations()[13];
  priors.gyro_bias_rad_s = Eigen::Vector3d::Zero();
  const PriorCalibration calibration = calibrateWithPriors(recording.data, CalibrationOptions(), priors);
  const Errors e = errorsOf(calibration.result, recording.truth, "all observable, priors given");
  ASSERT_TRUE(calibration.result.ok()) << calibration.result.reason();
  EXPECT_EQ(calibration.calibrations, 1);
  EXPECT_EQ(calibration.readout_time, CalibrationValueSource::kData);
  EXPECT_EQ(calibration.rotation, CalibrationValueSource::kData);
  EXPECT_EQ(calibration.gyro_bias, CalibrationValueSource::kData);
  // (From a start 4 ms off the readout may end elsewhere within its 1-sigma than from the default
  // start; what matters is that the data's answer is kept, not the stated one.)
  EXPECT_LT(std::abs(e.readout_ms), 2.0 * calibration.result.calibration.readout_time_sigma_s * 1e3);
  EXPECT_GT(std::abs(e.readout_ms - 4.0), 3.0 * calibration.result.calibration.readout_time_sigma_s * 1e3);
  bool said = false;
  for (const std::string& decision : calibration.decisions) {
    said = said || decision.find("readout time: the estimate") != std::string::npos;
  }
  EXPECT_TRUE(said) << "the 4 ms disagreement with the stated readout must be said";
  // A caller's hold wins over a prior.
  CalibrationOptions held;
  held.estimate_readout_time = false;
  held.readout_time_s = recording.truth.readout_time_s;
  const PriorCalibration caller = calibrateWithPriors(recording.data, held, priors);
  EXPECT_EQ(caller.readout_time, CalibrationValueSource::kCaller);
  EXPECT_EQ(caller.result.calibration.readout_time_s, recording.truth.readout_time_s);
}

TEST(CalibrationPriors, BadPriorsAreNamed) {
  CalibrationPriors priors;
  priors.source = "x.yaml";
  priors.readout_time_s = 2.0;
  EXPECT_NE(priors.validate().find("readout prior"), std::string::npos);
  priors.readout_time_s.reset();
  priors.imu_to_camera_rotation = Eigen::Matrix3d::Identity() * 2.0;
  const SyntheticRecording recording = makeRecording(SyntheticSpec());
  try {
    calibrateWithPriors(recording.data, CalibrationOptions(), priors);
    FAIL() << "a mount prior that is no rotation must be rejected";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("x.yaml"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deep_ois
