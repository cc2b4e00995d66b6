// The generic learned lens dynamics (core/ois/lens_dynamics_network.h) as the stabiliser model's
// learned stage: its state carried frame by frame, reset on a gap and on a jump back, its files
// (the network's and a model's that embeds it), its validation, and the per-camera adaptation
// recovering a known conditioning vector, lens map and output layer.
#include <gtest/gtest.h>

#include <cstdio>
#include <cmath>
#include <memory>
#include <random>

#include "deep_ois/core/ois/lens_dynamics_adaptation.h"
#include "deep_ois/core/ois/lens_dynamics_network.h"
#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stages/learned_lens_dynamics.h"

namespace deep_ois {
namespace {

constexpr double kFocalPx = 300.0;

// A small network with seeded random weights (4 hidden, 2 conditioning, 2 integrals, a skip path):
// what the pretraining exports, at a size a test can reason about.
std::shared_ptr<const LensDynamicsNetwork> smallNetwork(unsigned seed = 3) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> weight(0.0, 0.5);
  auto random = [&](long rows, long cols) {
    Eigen::MatrixXd m(rows, cols);
    for (long r = 0; r < rows; ++r)
      for (long c = 0; c < cols; ++c) m(r, c) = weight(rng);
    return m;
  };
  auto net = std::make_shared<LensDynamicsNetwork>();
  net->hidden_size = 4;
  net->conditioning_size = 2;
  net->step_s = 0.005;
  net->rate_scale_rad_s = 0.5;
  net->output_scale = 0.01;
  net->input_integrals_s = {0.1, 0.8};
  const long inputs = net->inputSize();
  net->w_input = random(12, inputs + 2);
  net->w_hidden = random(12, 4);
  net->b_input = random(12, 1);
  net->b_hidden = random(12, 1);
  net->w_output = random(2, 4);
  net->b_output = Eigen::Vector2d(0.1, -0.2);
  net->w_skip = 0.1 * random(2, inputs);
  net->default_conditioning = Eigen::Vector2d(0.1, -0.1);
  net->conditioning_spread = Eigen::Vector2d(0.5, 0.5);
  net->provenance.generator = "test";
  net->provenance.design_seed_begin = 1;
  net->provenance.design_seed_end = 11;
  EXPECT_EQ(net->validate(), "");
  return net;
}

StabiliserModel withNetwork(std::shared_ptr<const LensDynamicsNetwork> net,
                                 const Eigen::VectorXd& conditioning) {
  StabiliserModel p = genericLensDynamicsModel(net);
  p.get<LearnedLensDynamics>().conditioning = conditioning;
  return p;
}

// Hand-shake-like rates at 400 Hz from t0.
std::vector<CameraRateSample> shake(double t0, double duration_s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> phase(0.0, 6.283), amplitude(0.05, 0.3);
  const double frequencies[] = {0.7, 2.3, 5.1, 9.0};
  double a[3][4], ph[3][4];
  for (int axis = 0; axis < 3; ++axis)
    for (int k = 0; k < 4; ++k) a[axis][k] = amplitude(rng), ph[axis][k] = phase(rng);
  std::vector<CameraRateSample> rates;
  for (double t = 0.0; t <= duration_s + 1e-9; t += 1.0 / 400.0) {
    CameraRateSample s;
    s.stamp_s = t0 + t;
    for (int axis = 0; axis < 3; ++axis)
      for (int k = 0; k < 4; ++k) s.rate_rad_s(axis) += a[axis][k] * std::sin(6.283 * frequencies[k] * t + ph[axis][k]);
    rates.push_back(s);
  }
  return rates;
}

std::vector<Eigen::Vector2d> lensAtStamps(LensShiftPredictor& predictor, const std::vector<CameraRateSample>& rates) {
  std::vector<Eigen::Vector2d> lens;
  for (const CameraRateSample& s : rates) {
    predictor.addRate(s);
    lens.push_back(predictor.lensShiftAt(s.stamp_s));
  }
  return lens;
}

TEST(LensDynamics, CarriesItsStateFrameByFrame) {
  const auto net = smallNetwork();
  const StabiliserModel p = withNetwork(net, net->default_conditioning);
  const auto rates = shake(100.0, 3.0, 1);
  LensShiftPredictor whole(p, kFocalPx);
  const auto all = lensAtStamps(whole, rates);
  // Fed pair by pair (33 ms chunks) and queried between: the same lens.
  LensShiftPredictor chunked(p, kFocalPx);
  std::vector<Eigen::Vector2d> parts;
  for (std::size_t start = 0; start < rates.size(); start += 13) {
    for (std::size_t i = start; i < std::min(rates.size(), start + 13); ++i) {
      chunked.addRate(rates[i]);
      parts.push_back(chunked.lensShiftAt(rates[i].stamp_s));
    }
  }
  ASSERT_EQ(parts.size(), all.size());
  double largest = 0.0;
  for (std::size_t i = 0; i < all.size(); ++i) EXPECT_NEAR((parts[i] - all[i]).norm(), 0.0, 1e-12);
  for (const auto& v : all) largest = std::max(largest, v.norm());
  EXPECT_GT(largest, 0.5) << "the network must move the lens for this test to mean anything";
  // The state matters: a predictor started 2 s in does not give the same lens there.
  LensShiftPredictor late(p, kFocalPx);
  const std::vector<CameraRateSample> tail(rates.begin() + 800, rates.end());
  const auto late_lens = lensAtStamps(late, tail);
  EXPECT_GT((late_lens[40] - all[840]).norm(), 1e-3);
}

TEST(LensDynamics, ResetsOnAGapAndOnAJumpBack) {
  const auto net = smallNetwork();
  const StabiliserModel p = withNetwork(net, net->default_conditioning);
  const auto first = shake(10.0, 1.0, 2);
  const auto after_gap = shake(11.5, 1.0, 3);  // 0.5 s without gyro: longer than max_gap_s
  const auto back = shake(5.0, 1.0, 4);        // time goes back (a bag looping)
  LensShiftPredictor predictor(p, kFocalPx);
  lensAtStamps(predictor, first);
  const int resets = predictor.resets();
  const auto gap_lens = lensAtStamps(predictor, after_gap);
  EXPECT_EQ(predictor.resets(), resets + 1);
  LensShiftPredictor fresh(p, kFocalPx);
  const auto fresh_lens = lensAtStamps(fresh, after_gap);
  for (std::size_t i = 0; i < gap_lens.size(); ++i) ASSERT_NEAR((gap_lens[i] - fresh_lens[i]).norm(), 0.0, 1e-12);
  const auto back_lens = lensAtStamps(predictor, back);
  EXPECT_EQ(predictor.resets(), resets + 2);
  LensShiftPredictor fresh_back(p, kFocalPx);
  const auto fresh_back_lens = lensAtStamps(fresh_back, back);
  for (std::size_t i = 0; i < back_lens.size(); ++i)
    ASSERT_NEAR((back_lens[i] - fresh_back_lens[i]).norm(), 0.0, 1e-12);
}

TEST(LensDynamics, NetworkAndModelFilesRoundTrip) {
  const auto net = smallNetwork();
  const LensDynamicsNetwork again = LensDynamicsNetwork::fromYaml(net->toYaml());
  EXPECT_EQ(again.provenance.design_seed_end, 11u);
  EXPECT_EQ(again.input_integrals_s, net->input_integrals_s);
  StabiliserModelFile file;
  file.name = "test camera";
  file.parameters = withNetwork(net, Eigen::Vector2d(0.3, 0.2));
  file.parameters.get<LearnedLensDynamics>().output_map << 0.9, 0.1, -0.05, 1.1;
  file.camera.width = 360;
  file.camera.height = 270;
  file.camera.fx = file.camera.fy = kFocalPx;
  file.camera.cx = 180;
  file.camera.cy = 135;
  const StabiliserModelFile loaded = StabiliserModelFile::fromYaml(file.toYaml());
  ASSERT_TRUE(loaded.parameters.get<LearnedLensDynamics>().active());
  const auto rates = shake(0.0, 2.0, 5);
  LensShiftPredictor a(file.parameters, kFocalPx), b(loaded.parameters, kFocalPx);
  const auto lens_a = lensAtStamps(a, rates), lens_b = lensAtStamps(b, rates);
  for (std::size_t i = 0; i < lens_a.size(); ++i) ASSERT_NEAR((lens_a[i] - lens_b[i]).norm(), 0.0, 1e-6);
  // A model without the stage writes no learned_dynamics section (older readers keep reading it).
  StabiliserModelFile plain = file;
  plain.parameters = noLensMotion();
  EXPECT_EQ(plain.toYaml().find("learned_dynamics"), std::string::npos);
}

TEST(LensDynamics, BadFilesAndParametersNameTheField) {
  const auto net = smallNetwork();
  StabiliserModel p = withNetwork(net, Eigen::Vector3d(0, 0, 0));
  EXPECT_NE(p.validate().find("learned_dynamics.conditioning"), std::string::npos) << p.validate();
  std::string text = net->toYaml();
  text.replace(text.find("hidden_size: 4"), 14, "hidden_size: 5");
  try {
    LensDynamicsNetwork::fromYaml(text);
    FAIL() << "a network whose weights do not match its size must be refused";
  } catch (const LensDynamicsNetworkError& e) {
    EXPECT_NE(std::string(e.what()).find("w_input"), std::string::npos) << e.what();
  }
  // The network's step must be whole predictor steps.
  EXPECT_THROW(LensShiftPredictor(withNetwork(net, net->default_conditioning), kFocalPx, 0.003),
               std::invalid_argument);
}

// Lens motions of frame pairs (30 fps, 4 patches over a 20 ms readout) from a model.
StabiliserFitRecording recordingFrom(const StabiliserModel& truth, unsigned seed) {
  StabiliserFitRecording r;
  r.name = "synthetic " + std::to_string(seed);
  r.focal_px = kFocalPx;
  r.rates = shake(0.0, 4.0, seed);
  for (double t = 1.0; t < 3.9; t += 1.0 / 30.0)
    for (int patch = 0; patch < 4; ++patch) {
      LensMotionObservation o;
      o.readout_fraction = (patch + 0.5) / 4.0;
      o.t_a_s = t + 0.02 * o.readout_fraction;
      o.t_b_s = o.t_a_s + 1.0 / 30.0;
      r.observations.push_back(o);
    }
  const auto motion = predictLensMotion(truth, r);
  for (std::size_t i = 0; i < motion.size(); ++i) r.observations[i].motion_px = motion[i];
  return r;
}

TEST(LensDynamics, AdaptationRecoversTheCamerasConditioningAndMap) {
  const auto net = smallNetwork();
  StabiliserModel truth = withNetwork(net, Eigen::Vector2d(0.6, -0.5));
  truth.get<LearnedLensDynamics>().output_map << 1.2, 0.1, 0.0, 0.9;
  const std::vector<StabiliserFitRecording> recordings = {recordingFrom(truth, 11), recordingFrom(truth, 12)};
  StabiliserFitOptions options;
  LensDynamicsAdaptationOptions adaptation;
  adaptation.fit_output_map = true;
  adaptation.iterations = 30;
  adaptation.prior_weight_px2 = 1e-6;
  const LensDynamicsAdaptation adapted = adaptLensDynamics(net, recordings, options, adaptation);
  std::printf("[ figures  ] adaptation with map: rms %.5f -> %.3e px, conditioning (%.4f, %.4f), map(0,0) %.4f, %d passes\n",
              adapted.rms_start_px, adapted.rms_px, adapted.parameters.get<LearnedLensDynamics>().conditioning(0),
              adapted.parameters.get<LearnedLensDynamics>().conditioning(1), adapted.parameters.get<LearnedLensDynamics>().output_map(0, 0),
              adapted.passes);
  EXPECT_GT(adapted.rms_start_px, 0.05) << "the default conditioning must be wrong for this test";
  EXPECT_LT(adapted.rms_px, 0.01 * adapted.rms_start_px);
  EXPECT_NEAR(adapted.parameters.get<LearnedLensDynamics>().conditioning(0), 0.6, 0.05);
  EXPECT_NEAR(adapted.parameters.get<LearnedLensDynamics>().output_map(0, 0), 1.2, 0.05);
  // Without the map only the conditioning moves: it cannot explain a scaled lens as well.
  adaptation.fit_output_map = false;
  const LensDynamicsAdaptation conditioning_only = adaptLensDynamics(net, recordings, options, adaptation);
  std::printf("[ figures  ] adaptation without map: rms %.5f -> %.5f px, %d passes\n", conditioning_only.rms_start_px,
              conditioning_only.rms_px, conditioning_only.passes);
  EXPECT_GT(conditioning_only.rms_px, 2.0 * adapted.rms_px);
}

TEST(LensDynamics, OutputRefitRecoversALayer) {
  const auto net = smallNetwork();
  auto changed = std::make_shared<LensDynamicsNetwork>(*net);
  changed->w_output *= 1.3;
  changed->w_output(0, 1) += 0.4;
  const StabiliserModel truth = withNetwork(changed, net->default_conditioning);
  const std::vector<StabiliserFitRecording> recordings = {recordingFrom(truth, 21), recordingFrom(truth, 22)};
  StabiliserFitOptions options;
  const StabiliserModel start = withNetwork(net, net->default_conditioning);
  const StabiliserScore before = scoreStabiliser(start, recordings, options);
  const StabiliserModel refitted = refitLensDynamicsOutput(start, recordings, options, 1e-8);
  const StabiliserScore after = scoreStabiliser(refitted, recordings, options);
  std::printf("[ figures  ] output refit: rms %.5f -> %.3e px\n", before.rms_px, after.rms_px);
  EXPECT_GT(before.rms_px, 0.05);
  EXPECT_LT(after.rms_px, 0.01 * before.rms_px);
  // The shared network is not changed: the model carries its own copy.
  EXPECT_EQ(net->w_output, smallNetwork()->w_output);
}

}  // namespace
}  // namespace deep_ois
