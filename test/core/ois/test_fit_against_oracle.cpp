// The stabiliser fit (core/ois/stabiliser_fit.h) against the oracle of a design it can express: a
// generated design's own model (designModel) is the package's prediction with the exact stages, so
// on the fit's own cost it is the bar a fit of the right structure must reach. Here a
// constant-velocity Kalman stabiliser whose stroke the shake reaches, with nothing else the chain
// does not name: the composition "centring + linear dynamics" (the candidate table's row) can
// express it, and must reach the oracle's cost on the training recordings.
// docs/results/stabiliser_model.md, "Why the fit stops short of the oracle", has the measurements.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stages/stroke.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/imu_model.h"
#include "deep_ois/core/sim/stabiliser_design.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"

namespace deep_ois {
namespace {

constexpr double kFocalPx = 257.0;  // the benchmark's RE camera
constexpr double kStrokeDeg = 1.3;

// A Kalman stabiliser (training design 8 of the generator with what the chain does not name taken
// out: a 4 kHz loop, a symmetric box stroke that winds up, a second-order actuator, no noise).
sim::StabiliserDesign kalmanWithAReachedStroke() {
  sim::StabiliserDesign d;
  d.estimator.kind = sim::EstimatorKind::kKalman;
  d.estimator.corner_hz = 0.606;
  d.gain.gain_x = 1.04;
  d.gain.gain_y = 0.871;
  d.mount.noise_rad_s = 0.0;
  d.stroke.x_positive_deg = d.stroke.x_negative_deg = kStrokeDeg;
  d.stroke.y_positive_deg = d.stroke.y_negative_deg = kStrokeDeg;
  d.actuator.order = sim::ActuatorOrder::kSecond;
  d.actuator.bandwidth_hz = 87.7;
  d.actuator.damping = 0.468;
  EXPECT_EQ(d.validate(), "");
  return d;
}

// The benchmark's trace (design_traces.h, without the stabiliser's own gyro noise): 5 s of the simulator's hand-held motion (its default shake and pans), the camera's gyro (the
// simulator's IMU: 400 Hz, its noise and bias, as the benchmark's traces), and the lens motion of each of 8 row patches between frames at 30 frames/s (22 ms readout) from 1 s
// on, with the images' 0.1 px noise per axis when `noisy`.
StabiliserFitRecording recording(const sim::StabiliserDesign& design, std::uint32_t motion_seed, bool noisy) {
  const double duration_s = 5.0;
  const sim::CameraMotion motion(sim::CameraMotionConfig(), streamSeed(motion_seed, 1), 0.0, duration_s);
  const int steps = static_cast<int>(duration_s * sim::kDesignPhysicsRateHz);
  const sim::LensShiftGrid lens = sim::runDesign(
      design, kFocalPx, 0.0, steps, [&motion](double t) { return motion.angularVelocity(t); }, nullptr);
  StabiliserFitRecording r;
  r.name = "motion " + std::to_string(motion_seed);
  r.focal_px = kFocalPx;
  const sim::ImuConfig imu;
  for (const sim::ImuMeasurement& m : sim::sampleImu(imu, motion, streamSeed(motion_seed, 4), 0.0, duration_s))
    r.rates.push_back({m.stamp_s, imu.imu_to_camera_rotation * m.angular_velocity_rad_s});
  std::mt19937 rng(motion_seed);
  std::normal_distribution<double> noise(0.0, 0.1);
  const double frame_s = 1.0 / 30.0, readout_s = 0.022;
  for (double t = 1.0; t < duration_s - readout_s - frame_s; t += frame_s) {
    for (int patch = 0; patch < 8; ++patch) {
      LensMotionObservation o;
      o.readout_fraction = (patch + 0.5) / 8.0;
      o.t_a_s = t + o.readout_fraction * readout_s;
      o.t_b_s = o.t_a_s + frame_s;
      o.motion_px = lens.at(o.t_b_s) - lens.at(o.t_a_s);
      if (noisy) o.motion_px += Eigen::Vector2d(noise(rng), noise(rng));
      r.observations.push_back(o);
    }
  }
  return r;
}

TEST(FitAgainstOracle, TheLinearCompositionReachesAKalmanDesignsOracle) {
  // The chain alone fits this design's stroke at 3 x 2.3 deg (its high-pass stands in for the
  // Kalman filter); the composition's refit started from there and scanned only 0.7-1.3 times it,
  // so it ended 73 % above the oracle's cost with the stroke where it started. It scans the fit's
  // whole stroke grid now.
  const sim::StabiliserDesign design = kalmanWithAReachedStroke();
  std::vector<StabiliserFitRecording> training, evaluation;
  for (std::uint32_t seed = 101; seed <= 106; ++seed) training.push_back(recording(design, seed, true));
  evaluation.push_back(recording(design, 108u, false));
  StabiliserFitOptions options;
  options.check_timing = false;
  StabiliserFitOptions oracle_options = options;  // the design's own model runs at its physics step
  oracle_options.step_s = 1.0 / sim::kDesignPhysicsRateHz;
  const StabiliserModel oracle = sim::designModel(design);
  const double oracle_cost = stabiliserFitCost(oracle, training, oracle_options);

  const StabiliserFitResult chain = fitStabiliser(training, options);
  const StabiliserFitResult composed = refitStabiliserStages(
      chain.parameters, {"centring", "linear_dynamics:1hz_x8", "stroke", "actuator"}, training, options);
  const double composed_cost = stabiliserFitCost(composed.parameters, training, options);
  EXPECT_LT(composed_cost, 1.02 * oracle_cost) << "oracle " << oracle_cost;
  // The x stroke is met in these motions (the y lens, at gain 0.87, hardly reaches its stroke, so
  // the data do not place it).
  EXPECT_NEAR(composed.parameters.get<StrokeValues>().stroke_x_deg, kStrokeDeg, 0.1 * kStrokeDeg);

  // On a recording it was not fitted on it explains most of the lens motion (83 % before the
  // whole grid was scanned), though less than the oracle (the y stroke it could not place).
  const StabiliserScore kept = scoreStabiliser(composed.parameters, evaluation, options);
  const StabiliserScore best = scoreStabiliser(oracle, evaluation, oracle_options);
  EXPECT_GT(1.0 - kept.rms_px / kept.rms_without_model_px, 0.88);
  EXPECT_GT(1.0 - best.rms_px / best.rms_without_model_px, 0.99);
}

}  // namespace
}  // namespace deep_ois
