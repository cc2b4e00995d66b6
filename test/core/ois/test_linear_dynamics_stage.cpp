// The linear-dynamics stage (src/core/ois/stages/linear_dynamics_stage.cpp): its runner is the
// basis' filter times its coefficients, its closed-form fit recovers known coefficients through a
// held actuator and stands in for a chain it was not written as, and a model of it is a file that
// loads and predicts as it was saved.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/linear_dynamics_rls.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {
namespace {

constexpr double kFocalPx = 500.0;

// A hand shake of 12 s at 400 Hz (all three axes), frame pairs at 30 fps with 12 row patches.
StabiliserFitRecording shake() {
  StabiliserFitRecording recording;
  recording.name = "shake";
  recording.focal_px = kFocalPx;
  for (double t = 0.0; t <= 12.0; t += 1.0 / 400.0) {
    const Eigen::Vector3d w(0.05 * std::sin(6.283 * 1.1 * t) + 0.03 * std::sin(6.283 * 4.3 * t + 1.0) +
                                0.01 * std::sin(6.283 * 9.7 * t),
                            0.06 * std::sin(6.283 * 0.8 * t + 0.5) + 0.025 * std::sin(6.283 * 6.1 * t) +
                                0.01 * std::sin(6.283 * 13.1 * t + 0.3),
                            0.03 * std::sin(6.283 * 0.4 * t));
    recording.rates.push_back({t, w});
  }
  for (double stamp = 1.0; stamp + 1.0 / 30.0 < 11.9; stamp += 1.0 / 30.0) {
    for (int i = 0; i < 12; ++i) {
      LensMotionObservation o;
      o.t_a_s = stamp + 0.02 * (i + 0.5) / 12.0;
      o.t_b_s = o.t_a_s + 1.0 / 30.0;
      recording.observations.push_back(o);
    }
  }
  return recording;
}

// The recording's lens motions as `truth` predicts them.
StabiliserFitRecording observed(const StabiliserModel& truth) {
  StabiliserFitRecording recording = shake();
  const auto motion = predictLensMotion(truth, recording, 1e-3, 0.0);
  for (std::size_t k = 0; k < motion.size(); ++k) recording.observations[k].motion_px = motion[k];
  return recording;
}

StabiliserModel chain() {
  StabiliserModel p;
  p.get<CentringValues>().gain << 0.0, 0.95, -1.02, 0.0;
  p.get<CentringValues>().highpass_corner_hz = 0.5;
  p.get<ActuatorValues>().actuator_natural_hz = 40.0;
  p.get<ActuatorValues>().actuator_damping = 0.7;
  p.get<ActuatorValues>().sensor_lag_s = 0.001;
  p.get<StrokeValues>().stroke_x_deg = 5.0;  // never met by the shake: the chain is linear
  p.get<StrokeValues>().stroke_y_deg = 5.0;
  return p;
}

LinearDynamicsBasisSpec basis() {
  LinearDynamicsBasisSpec spec;
  spec.pole_hz = 1.0;
  spec.order = 6;
  return spec;
}

// A linear-dynamics model with deterministic coefficients (focal units).
StabiliserModel knownLinearDynamics() {
  StabiliserModel p = chain().only({"linear_dynamics", "stroke", "actuator"});
  LinearDynamicsValues& linear = p.get<LinearDynamicsValues>();
  linear.basis = basis();
  linear.coefficients.resize(2, 3 * basis().order);
  for (long j = 0; j < linear.coefficients.cols(); ++j) {
    linear.coefficients(0, j) = 0.15 * std::sin(1.3 * j + 0.2);
    linear.coefficients(1, j) = 0.15 * std::cos(0.7 * j + 0.9);
  }
  return p;
}

// Step 1 of the fit alone: `stages` of chain() with the basis' coefficients solved in closed form
// from zero (twice, as the fit does), the rest held.
StabiliserModel solvedLinearDynamics(const std::vector<std::string>& stages,
                                     const StabiliserFitRecording& recording, double ridge) {
  StabiliserModel model = chain().only(stages);
  stabiliserStage("linear_dynamics").start(*model.values("linear_dynamics"), "1hz_x6");
  StabiliserFitOptions options;
  for (int solve = 0; solve < 2; ++solve)
    model = solveLinearDynamicsCoefficients(model, {recording}, options, ridge);
  return model;
}

double rms(const std::vector<Eigen::Vector2d>& v) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const Eigen::Vector2d& x : v)
    if (x.allFinite()) sum += x.squaredNorm(), ++n;
  return std::sqrt(sum / static_cast<double>(n));
}

// The RMS (px) of `model`'s lens-motion error on the recording, and of the observed motion, over
// the observations it predicts (after a 1 s warm-up).
std::pair<double, double> predictionErrorAndMotion(const StabiliserModel& model,
                                                   const StabiliserFitRecording& recording) {
  const auto predicted = predictLensMotion(model, recording, 1e-3, 1.0);
  std::vector<Eigen::Vector2d> error, motion;
  for (std::size_t k = 0; k < predicted.size(); ++k) {
    if (!predicted[k].allFinite()) continue;
    error.push_back(predicted[k] - recording.observations[k].motion_px);
    motion.push_back(recording.observations[k].motion_px);
  }
  return {rms(error), rms(motion)};
}

TEST(LinearDynamicsStage, TheRunnerIsTheBasisFilterTimesItsCoefficients) {
  // Without an actuator or a stroke that acts, the lens is f C x for the basis state x of the rate
  // held over each step (a constant rate: no interpolation between samples).
  StabiliserModel p = knownLinearDynamics().only({"linear_dynamics"});
  LensShiftPredictor predictor(p, kFocalPx);
  LinearDynamicsBasis reference(basis(), 1e-3);
  const Eigen::Vector3d rate(0.02, -0.03, 0.01);
  for (int k = 0; k <= 500; ++k) predictor.addRate({0.001 * k, rate});
  for (int k = 0; k < 500; ++k) reference.advance(rate);
  const Eigen::Vector2d expected = kFocalPx * (p.get<LinearDynamicsValues>().coefficients * reference.state());
  EXPECT_LT((predictor.lensShiftAt(0.5) - expected).norm(), 1e-9 * (1.0 + expected.norm()));
  EXPECT_GT(expected.norm(), 0.1);
}

TEST(LinearDynamicsStage, TheClosedFormFitRecoversKnownCoefficientsThroughTheActuator) {
  const StabiliserModel truth = knownLinearDynamics();
  const StabiliserFitRecording recording = observed(truth);
  const StabiliserModel fitted = solvedLinearDynamics({"linear_dynamics", "stroke", "actuator"}, recording, 0.0);
  EXPECT_EQ(fitted.stageNames(), truth.stageNames());
  const auto [error_px, motion_px] = predictionErrorAndMotion(fitted, recording);
  EXPECT_LT(error_px, 1e-6 * motion_px);
  EXPECT_GT(motion_px, 0.5);  // pixels: the shake moves the lens
}

TEST(LinearDynamicsStage, TheRecursiveLeastSquaresOnItsEvidenceRecoversKnownCoefficients) {
  // The online learner's path: the evidence (one run of the chain per coefficient column) about
  // coefficients that are all wrong (zero), streamed into the recursive least squares with its
  // default prior (20 lens motions towards zero, against ~4,000 rows): the chain is linear in them
  // through the actuator, so the lens motions come back (the coefficients themselves less well:
  // the basis' states are strongly correlated, and the covariance form loses digits on them).
  const StabiliserModel truth = knownLinearDynamics();
  const StabiliserFitRecording recording = observed(truth);
  StabiliserModel start = truth;
  start.get<LinearDynamicsValues>().coefficients.setZero();
  StabiliserFitOptions options;
  const LinearDynamicsEvidence evidence = linearDynamicsEvidence(start, {recording}, options);
  ASSERT_GT(evidence.rows(), 1000);
  LinearDynamicsRls rls(start.get<LinearDynamicsValues>().coefficients, LinearDynamicsRlsOptions());
  rls.add(evidence);
  StabiliserModel learned = start;
  learned.get<LinearDynamicsValues>().coefficients = rls.coefficients();
  const auto [error_px, motion_px] = predictionErrorAndMotion(learned, recording);
  EXPECT_LT(error_px, 0.02 * motion_px) << rls.coefficients();
}

TEST(LinearDynamicsStage, StandsInForACentringChainInsideTheStroke) {
  // The chain's first-order centring is a linear filter of the rate inside the stroke: the basis
  // (corner 1 Hz, 6 functions per axis) explains nearly all of it, the actuator held.
  const StabiliserFitRecording recording = observed(chain());
  const StabiliserModel fitted = solvedLinearDynamics({"linear_dynamics", "stroke", "actuator"}, recording, 1e-5);
  StabiliserFitOptions options;
  const StabiliserScore score = scoreStabiliser(fitted, {recording}, options);
  EXPECT_LT(score.rms_px, 0.02 * score.rms_without_model_px) << score.rms_px;
  EXPECT_EQ(stabiliserComposition(fitted),
            (std::vector<std::string>{"linear_dynamics:1hz_x6", "stroke", "actuator"}));
  // A model without the stage (or before its basis is started) is refused.
  EXPECT_THROW(solveLinearDynamicsCoefficients(chain(), {recording}, options), std::invalid_argument);
  EXPECT_THROW(solveLinearDynamicsCoefficients(chain().only({"linear_dynamics", "stroke"}), {recording}, options),
               std::invalid_argument);
}

TEST(LinearDynamicsStage, AModelFileOfItLoadsAndPredictsAsSaved) {
  StabiliserModelFile file;
  file.name = "linear dynamics";
  file.parameters = knownLinearDynamics();
  file.camera = {640, 480, kFocalPx, kFocalPx, 319.5, 239.5, 0.03, 30.0};
  const std::string path = ::testing::TempDir() + "/deep_ois_linear_dynamics_" +
                           std::to_string(::getpid()) + ".yaml";
  file.save(path);
  const StabiliserModelFile loaded = StabiliserModelFile::load(path);
  EXPECT_EQ(loaded.parameters.stageNames(), file.parameters.stageNames());
  EXPECT_EQ(loaded.parameters.get<LinearDynamicsValues>().basis.order, basis().order);
  const StabiliserFitRecording recording = shake();
  const auto a = predictLensMotion(file.parameters, recording, 1e-3, 1.0);
  const auto b = predictLensMotion(loaded.parameters, recording, 1e-3, 1.0);
  double largest = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (a[k].allFinite()) largest = std::max(largest, (a[k] - b[k]).cwiseAbs().maxCoeff());
  EXPECT_LT(largest, 1e-6);  // the file's 10 significant digits
  // A stage list naming an unknown stage is refused, naming it.
  try {
    knownLinearDynamics().only({"linear_dynamics", "no_such_stage"});
    ADD_FAILURE() << "an unknown stage was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_stage"), std::string::npos);
  }
  std::string text = file.toYaml();
  text.replace(text.find("stages: ["), 9, "stages: [no_such_stage, ");
  try {
    StabiliserModelFile::fromYaml(text);
    ADD_FAILURE() << "a file naming an unknown stage was accepted";
  } catch (const StabiliserModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_stage"), std::string::npos);
  }
  std::remove(path.c_str());
}

// The known linear dynamics through a soft stroke the shake meets (60 % of its largest command).
StabiliserModel knownLinearDynamicsThroughASoftStroke() {
  StabiliserModel truth = knownLinearDynamics();
  LensShiftPredictor predictor(truth, kFocalPx);
  Eigen::Vector2d largest = Eigen::Vector2d::Zero();
  for (const CameraRateSample& sample : shake().rates) {
    predictor.addRate(sample);
    largest = largest.cwiseMax(predictor.lensShiftAt(sample.stamp_s).cwiseAbs());
  }
  StrokeValues& stroke = truth.get<StrokeValues>();
  stroke.soft_stroke = true;
  stroke.stroke_x_deg = std::atan(0.6 * largest.x() / kFocalPx) * 180.0 / 3.14159265358979;
  stroke.stroke_y_deg = std::atan(0.6 * largest.y() / kFocalPx) * 180.0 / 3.14159265358979;
  return truth;
}

TEST(LinearDynamicsStage, TheTwoStepFitFindsTheStrokeAroundIt) {
  // Step 1 alone (the coefficients in closed form through the fitted chain's far stroke) cannot
  // explain a lens the stroke squashes; step 2 (the solver on the stroke and actuator, the
  // coefficients solved again between its rounds) finds the stroke and the coefficients together.
  const StabiliserModel truth = knownLinearDynamicsThroughASoftStroke();
  const StabiliserFitRecording recording = observed(truth);
  StabiliserFitOptions options;
  const std::vector<std::string> stages = {"linear_dynamics:1hz_x6", "stroke:soft", "actuator"};
  StabiliserModel step_one = chain().only(stages);
  step_one.get<StrokeValues>().soft_stroke = true;
  stabiliserStage("linear_dynamics").start(*step_one.values("linear_dynamics"), "1hz_x6");
  for (int solve = 0; solve < 2; ++solve)
    step_one = solveLinearDynamicsCoefficients(step_one, {recording}, options);
  const StabiliserScore one = scoreStabiliser(step_one, {recording}, options);

  const StabiliserFitResult joint = refitStabiliserStages(chain(), stages, {recording}, options);
  const StabiliserScore both = scoreStabiliser(joint.parameters, {recording}, options);
  EXPECT_EQ(stabiliserComposition(joint.parameters), stages);
  EXPECT_LT(both.rms_px, 0.3 * one.rms_px) << both.rms_px << " px after step 2, " << one.rms_px
                                           << " px after step 1";
  EXPECT_LT(both.rms_px, 0.03 * both.rms_without_model_px) << both.rms_px;
  const double stroke_x = joint.parameters.get<StrokeValues>().stroke_x_deg;
  EXPECT_NEAR(stroke_x, truth.get<StrokeValues>().stroke_x_deg, 0.2 * truth.get<StrokeValues>().stroke_x_deg);
}

TEST(LinearDynamicsStage, ItsBasisIsItsTokensVariant) {
  StabiliserModel p = chain().only({"linear_dynamics", "stroke"});
  const StabiliserStage& stage = stabiliserStage("linear_dynamics");
  stage.start(*p.values("linear_dynamics"), "0.5+20hz_x12");
  const LinearDynamicsValues& linear = p.get<LinearDynamicsValues>();
  EXPECT_EQ(linear.basis.pole_hz, 0.5);
  EXPECT_EQ(linear.basis.second_pole_hz, 20.0);
  EXPECT_EQ(linear.basis.order, 12);
  EXPECT_EQ(linear.coefficients.cols(), 36);
  EXPECT_EQ(stabiliserComposition(p), (std::vector<std::string>{"linear_dynamics:0.5+20hz_x12", "stroke"}));
  for (const char* bad : {"1hz", "hz_x8", "1hz_x", "1hz_x8 ", "-1hz_x8", "1+hz_x8", "1hz_x0"}) {
    try {
      stage.start(*p.values("linear_dynamics"), bad);
      ADD_FAILURE() << "the variant '" << bad << "' was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  stage.start(*p.values("linear_dynamics"), nullptr);  // left out
  EXPECT_EQ(stabiliserComposition(p), (std::vector<std::string>{"stroke"}));
}

}  // namespace
}  // namespace deep_ois
