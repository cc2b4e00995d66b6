// Each stage's runner (core/ois/stabiliser_signal.h) against a response written down in closed
// form: the runner is built by its stage (StabiliserStage::runner), its inputs are written into the
// signal by hand, and its output is compared with the formula, not with another implementation.
// Covered here: centring (step and sine), stroke (box, ellipse, soft, anti-windup), excursion
// re-centring (the steady state it settles to), pan detection (when it lets go and takes hold
// again), actuator (step response, sensor lag, sine), actuator coupling, and the sampled
// controller's Hall actuator (first-order step after its delay). The linear-dynamics stage's
// runner has its own (test_linear_dynamics_stage.cpp); the sampled controller's other stages are
// pinned against the simulator's designs (test_stabiliser_lens_golden.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFocalPx = 1000.0;

// The runner of `stage` for the model's values of it, at step h.
std::unique_ptr<StabiliserStageRunner> runnerOf(const std::string& stage, const StabiliserModel& model,
                                                double h) {
  const StabiliserStage& description = stabiliserStage(stage);
  std::unique_ptr<StabiliserStageRunner> runner =
      description.runner(*model.values(stage), model, StabiliserRunContext{kFocalPx, h});
  if (!runner) throw std::logic_error(stage + " does not act for these values");
  return runner;
}

double strokePixels(double degrees) { return kFocalPx * std::tan(degrees * kPi / 180.0); }

// Second-order step response x(t) of x'' = wn^2 (1 - x) - 2 zeta wn x' from rest, zeta < 1.
double secondOrderStep(double t, double natural_hz, double zeta) {
  if (t <= 0.0) return 0.0;
  const double wn = 2.0 * kPi * natural_hz;
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  return 1.0 - std::exp(-zeta * wn * t) *
                   (std::cos(wd * t) + zeta / std::sqrt(1.0 - zeta * zeta) * std::sin(wd * t));
}

TEST(StageResponses, CentringIsALeakyIntegralOfTheRate) {
  // A constant rate w about the camera's y axis: theta_y(t) = w / c (1 - e^{-c t}) (exact for a
  // rate constant over each step), the command f tan(theta_y) along x (the ideal gain).
  StabiliserModel model(std::vector<std::string>{"centring"});
  CentringValues& centring = model.get<CentringValues>();
  centring.highpass_corner_hz = 0.5;
  const double c = 2.0 * kPi * centring.highpass_corner_hz;
  const double h = 1e-3, w = 0.08;
  auto runner = runnerOf("centring", model, h);
  StabiliserSignal signal;
  runner->reset(signal);
  signal.rate_rad_s = Eigen::Vector3d(0.0, w, 0.0);
  double worst = 0.0;
  for (int n = 1; n <= 3000; ++n) {
    runner->advance(signal);
    const double theta = w / c * -std::expm1(-c * n * h);
    worst = std::max(worst, std::abs(signal.lens_px.x() - kFocalPx * std::tan(theta)));
    ASSERT_NEAR(signal.lens_px.y(), 0.0, 1e-12);
  }
  EXPECT_LT(worst, 1e-9);

  // A sine of small amplitude: in steady state the angle is the rate through 1 / (s + c), so its
  // amplitude is A / sqrt(omega^2 + c^2) and it leads the rate's integral by atan(c / omega).
  const double amplitude = 0.01, omega = 2.0 * kPi * 2.0;
  runner->reset(signal);
  double largest = 0.0;
  for (int n = 1; n <= 8000; ++n) {
    const double t_mid = (n - 0.5) * h;  // the predictor gives the rate at the step's middle
    signal.rate_rad_s = Eigen::Vector3d(0.0, amplitude * std::sin(omega * t_mid), 0.0);
    runner->advance(signal);
    if (n > 6000) largest = std::max(largest, std::abs(signal.angle_rad.y()));
  }
  const double expected = amplitude / std::hypot(omega, c);
  EXPECT_NEAR(largest / expected, 1.0, 1e-3);
}

TEST(StageResponses, StrokeLimitsTheCommandAsItsShapeSays) {
  const double h = 1e-3;
  const Eigen::Vector2d raw(30.0, -12.0);  // px, beyond a 1 deg x 0.5 deg stroke in x only
  const double sx = strokePixels(1.0), sy = strokePixels(0.5);
  auto limited = [&](bool circular, bool soft) {
    StabiliserModel model(std::vector<std::string>{"stroke"});
    StrokeValues& stroke = model.get<StrokeValues>();
    stroke.stroke_x_deg = 1.0, stroke.stroke_y_deg = 0.5;
    stroke.circular_stroke = circular, stroke.soft_stroke = soft;
    auto runner = runnerOf("stroke", model, h);
    StabiliserSignal signal;
    runner->reset(signal);
    signal.raw_command_px = raw;
    runner->advance(signal);
    EXPECT_EQ(signal.lens_px, signal.command_px);  // no actuator after it
    return signal.command_px;
  };
  // Box: each axis clamped.
  EXPECT_NEAR(limited(false, false).x(), sx, 1e-12);
  EXPECT_NEAR(limited(false, false).y(), -sy, 1e-12);
  // Ellipse: scaled back along the command to r = |(u_x / s_x, u_y / s_y)| = 1.
  const double r = std::hypot(raw.x() / sx, raw.y() / sy);
  EXPECT_NEAR((limited(true, false) - raw / r).norm(), 0.0, 1e-12);
  // Soft box: s tanh(u / s) per axis; soft ellipse: radially, u tanh(r) / r.
  EXPECT_NEAR(limited(false, true).x(), sx * std::tanh(raw.x() / sx), 1e-12);
  EXPECT_NEAR(limited(false, true).y(), sy * std::tanh(raw.y() / sy), 1e-12);
  EXPECT_NEAR((limited(true, true) - raw * (std::tanh(r) / r)).norm(), 0.0, 1e-12);
  // Inside the stroke a hard one lets the command through unchanged.
  StabiliserModel model(std::vector<std::string>{"stroke"});
  auto runner = runnerOf("stroke", model, h);
  StabiliserSignal signal;
  runner->reset(signal);
  signal.raw_command_px = Eigen::Vector2d(3.0, -2.0);
  runner->advance(signal);
  EXPECT_EQ(signal.command_px, Eigen::Vector2d(3.0, -2.0));
}

TEST(StageResponses, AntiWindupHoldsTheAngleWhereTheCommandMeetsTheStroke) {
  // Centring then a box stroke with anti-windup, a constant rate that drives the command past the
  // stroke: the angle stays at atan(s / f) (the ideal gain), so the lens leaves the stroke the
  // step the rate turns, where without anti-windup it would have to unwind first.
  StabiliserModel model(std::vector<std::string>{"centring", "stroke"});
  model.get<CentringValues>().highpass_corner_hz = 0.1;
  model.get<StrokeValues>().stroke_x_deg = 0.5;
  model.get<StrokeValues>().anti_windup = true;
  const double h = 1e-3;
  StabiliserChain chain(stabiliserRunners(model, {kFocalPx, h}));
  chain.reset();
  for (int n = 0; n < 500; ++n) chain.step(Eigen::Vector3d(0.0, 0.2, 0.0), Eigen::Vector3d(0.0, 0.2, 0.0));
  const double sx = strokePixels(0.5);
  EXPECT_NEAR(chain.signal().lens_px.x(), sx, 1e-9);
  EXPECT_NEAR(chain.signal().angle_rad.y(), std::atan(sx / kFocalPx), 1e-12);
  // The rate turns: one step of leak from the held angle.
  const double c = 2.0 * kPi * 0.1;
  const double held = std::atan(sx / kFocalPx);
  const double next = std::exp(-c * h) * held + (-std::expm1(-c * h) / c) * -0.2;
  chain.step(Eigen::Vector3d(0.0, -0.2, 0.0), Eigen::Vector3d(0.0, -0.2, 0.0));
  EXPECT_NEAR(chain.signal().lens_px.x(), kFocalPx * std::tan(next), 1e-9);
  EXPECT_LT(chain.signal().lens_px.x(), sx);
}

TEST(StageResponses, ExcursionRecentringSettlesWhereTheWidenedLeakBalancesTheRate) {
  // Centring, excursion re-centring and a stroke large enough never to be met: a constant rate
  // settles the angle where c (1 + k e^2) theta = w, e = f tan(theta) / s (the excursion).
  StabiliserModel model(std::vector<std::string>{"centring", "excursion_centring", "stroke"});
  model.get<CentringValues>().highpass_corner_hz = 0.5;
  model.get<ExcursionCentringValues>().excursion_centring = 4.0;
  model.get<StrokeValues>().stroke_x_deg = model.get<StrokeValues>().stroke_y_deg = 2.0;
  const double c = 2.0 * kPi * 0.5, k = 4.0, w = 0.1, s = strokePixels(2.0);
  StabiliserChain chain(stabiliserRunners(model, {kFocalPx, 1e-3}));
  chain.reset();
  for (int n = 0; n < 20000; ++n) chain.step(Eigen::Vector3d(0.0, w, 0.0), Eigen::Vector3d(0.0, w, 0.0));
  // The balance by bisection (its left side grows with theta).
  double low = 0.0, high = w / c;
  for (int i = 0; i < 200; ++i) {
    const double theta = 0.5 * (low + high);
    const double e = kFocalPx * std::tan(theta) / s;
    (c * (1.0 + k * e * e) * theta < w ? low : high) = theta;
  }
  const double settled = chain.signal().angle_rad.y();
  EXPECT_NEAR(settled, 0.5 * (low + high), 1e-9);
  EXPECT_LT(settled, 0.8 * w / c);  // well short of the plain leak's w / c: the stage acts
}

TEST(StageResponses, PanDetectionLetsGoWhenTheSmoothedRateCrossesItsThreshold) {
  // The smoothed |rate| of a rate switched on at w is w (1 - e^{-t / tau}): it crosses the
  // threshold at t = -tau ln(1 - threshold / w); switched off, it decays as e^{-t / tau} and takes
  // hold again below 0.7 x the threshold.
  StabiliserModel model(std::vector<std::string>{"pan_detection"});
  PanDetectionValues& pan = model.get<PanDetectionValues>();
  pan.pan_detection_rate_rad_s = 0.5;
  pan.pan_detection_time_constant_s = 0.1;
  pan.pan_release_corner_hz = 4.0;
  const double h = 1e-3, w = 0.8, tau = 0.1, threshold = 0.5;
  auto runner = runnerOf("pan_detection", model, h);
  StabiliserSignal signal;
  runner->reset(signal);
  signal.rate_rad_s = Eigen::Vector3d(w * 0.6, w * 0.8, 0.3);  // |pan, tilt| = w; roll ignored
  int let_go = -1;
  for (int n = 1; n <= 1000 && let_go < 0; ++n) {
    runner->advance(signal);
    if (signal.released) let_go = n;
  }
  EXPECT_EQ(let_go, static_cast<int>(std::ceil(-tau * std::log(1.0 - threshold / w) / h)));
  EXPECT_NEAR(signal.release_decay, std::exp(-2.0 * kPi * 4.0 * h), 1e-15);
  // Held steady until the smoothed rate, from w (1 - e^{-let_go h / tau}) after 1000 steps ...
  for (int n = let_go + 1; n <= 1000; ++n) runner->advance(signal);
  const double smoothed = w * -std::expm1(-1000 * h / tau);
  signal.rate_rad_s.setZero();
  int hold = -1;
  for (int n = 1; n <= 2000 && hold < 0; ++n) {
    runner->advance(signal);
    if (!signal.released) hold = n;
  }
  // ... decays below 0.7 x the threshold.
  EXPECT_EQ(hold, static_cast<int>(std::ceil(-tau * std::log(0.7 * threshold / smoothed) / h)));
}

TEST(StageResponses, ActuatorIsASecondOrderSystemBehindItsSensorLag) {
  StabiliserModel model(std::vector<std::string>{"stroke", "actuator"});
  model.get<StrokeValues>().stroke_x_deg = model.get<StrokeValues>().stroke_y_deg = 2.0;
  ActuatorValues& actuator = model.get<ActuatorValues>();
  actuator.actuator_natural_hz = 30.0;
  actuator.actuator_damping = 0.6;
  const double h = 1e-4, step_px = 5.0;
  for (const int lag_steps : {0, 7}) {
    actuator.sensor_lag_s = lag_steps * h;
    auto runner = runnerOf("actuator", model, h);
    StabiliserSignal signal;
    runner->reset(signal);
    double worst = 0.0;
    for (int n = 1; n <= 2000; ++n) {
      signal.command_px = Eigen::Vector2d(step_px, -step_px);  // a step held from the first step
      runner->advance(signal);
      // Exact for a command held over each step; the lag delays it by whole steps here.
      const double expected = step_px * secondOrderStep((n - lag_steps) * h, 30.0, 0.6);
      worst = std::max({worst, std::abs(signal.lens_px.x() - expected),
                        std::abs(signal.lens_px.y() + expected)});
    }
    EXPECT_LT(worst, 1e-9) << "lag " << lag_steps << " steps";
  }
  // A sine command: in steady state the amplitude is |H(j omega)| = wn^2 / |wn^2 - omega^2 + 2 j
  // zeta wn omega| (the hold over a 0.1 ms step changes it by less than 1e-3).
  actuator.sensor_lag_s = 0.0;
  auto runner = runnerOf("actuator", model, h);
  StabiliserSignal signal;
  runner->reset(signal);
  const double wn = 2.0 * kPi * 30.0, omega = 2.0 * kPi * 20.0;
  double largest = 0.0;
  for (int n = 1; n <= 4000; ++n) {
    signal.command_px = Eigen::Vector2d(step_px * std::sin(omega * (n - 0.5) * h), 0.0);
    runner->advance(signal);
    if (n > 3000) largest = std::max(largest, std::abs(signal.lens_px.x()));
  }
  const double gain = wn * wn / std::hypot(wn * wn - omega * omega, 2.0 * 0.6 * wn * omega);
  EXPECT_NEAR(largest / (step_px * gain), 1.0, 1e-3);
}

TEST(StageResponses, ActuatorCouplingMixesTheAxes) {
  StabiliserModel model(std::vector<std::string>{"actuator_coupling"});
  model.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, -0.05);
  auto runner = runnerOf("actuator_coupling", model, 1e-3);
  StabiliserSignal signal;
  runner->reset(signal);
  signal.lens_px = Eigen::Vector2d(4.0, -2.0);
  runner->advance(signal);
  EXPECT_NEAR(signal.lens_px.x(), 4.0 + 0.1 * -2.0, 1e-15);
  EXPECT_NEAR(signal.lens_px.y(), -2.0 - 0.05 * 4.0, 1e-15);
}

TEST(StageResponses, HallActuatorOfFirstOrderFollowsItsCommandAfterItsDelay) {
  // The sampled controller's lens loop, first order of bandwidth b, linear Hall sensor: a command
  // step is followed as 1 - e^{-2 pi b (t - delay)}, the delay counted in steps plus the one step a
  // sampled controller's update waits.
  StabiliserModel model(std::vector<std::string>{});
  model.set(TravelValues()).x_positive_deg = 2.0;
  HallActuatorValues hall;
  hall.order = "first";
  hall.bandwidth_hz = 25.0;
  hall.delay_s = 0.002;
  model.set(hall);
  const double h = 1e-3, step_px = 3.0;
  auto runner = runnerOf("hall_actuator", model, h);
  StabiliserSignal signal;
  runner->reset(signal);
  const int delay_steps = 2 + 1;
  double worst = 0.0;
  for (int n = 1; n <= 200; ++n) {
    signal.command_px = Eigen::Vector2d(step_px, 0.0);
    runner->advance(signal);
    const int moving = n - delay_steps;  // steps the lens has followed the step
    const double expected = moving > 0 ? step_px * -std::expm1(-2.0 * kPi * 25.0 * moving * h) : 0.0;
    worst = std::max(worst, std::abs(signal.lens_px.x() - expected));
  }
  EXPECT_LT(worst, 1e-12);
}

}  // namespace
}  // namespace deep_ois
