// The linear-dynamics basis (core/ois/linear_dynamics_basis.h): its step and sine responses
// against the Laguerre functions' closed forms, the orthonormality of the two-pole variant, the
// closed-form fit recovering the simulator's own constant-velocity Kalman stabiliser (runDesign)
// on held-out motion, and the fit's refusals of bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/stabiliser_design.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"

namespace deep_ois {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The step response of Laguerre function k (0-based, pole a rad/s) to a unit rate:
// int_0^t sqrt(2a) e^{-a tau} L_k(2 a tau) d tau
//   = sqrt(2a) / a * sum_m C(k, m) (-2)^m (1 - e^{-at} sum_{i<=m} (at)^i / i!).
double laguerreStep(int k, double a, double t) {
  double sum = 0.0, binomial = 1.0;
  for (int m = 0; m <= k; ++m) {
    if (m > 0) binomial *= static_cast<double>(k - m + 1) / m;
    double partial = 0.0, term = 1.0;
    for (int i = 0; i <= m; ++i) {
      if (i > 0) term *= a * t / i;
      partial += term;
    }
    sum += binomial * std::pow(-2.0, m) * (1.0 - std::exp(-a * t) * partial);
  }
  return std::sqrt(2.0 * a) / a * sum;
}

// The continuous transfer function of function k at s.
std::complex<double> laguerreResponse(int k, double a, std::complex<double> s) {
  return std::sqrt(2.0 * a) / (s + a) * std::pow((s - a) / (s + a), k);
}

TEST(LinearDynamicsBasis, StepResponseIsTheLaguerreFunctionsIntegral) {
  LinearDynamicsBasisSpec spec;
  spec.pole_hz = 2.0;
  spec.order = 7;
  const double step_s = 1e-3, a = 2.0 * kPi * spec.pole_hz;
  LinearDynamicsBasis basis(spec, step_s);
  ASSERT_EQ(basis.size(), 21);
  // A rate held over every step: the exact discretisation meets the closed form at each step's end.
  for (int j = 1; j <= 3000; ++j) {
    const Eigen::VectorXd& x = basis.advance(Eigen::Vector3d(0.0, 1.0, 0.0));
    if (j % 250 != 0) continue;
    for (int k = 0; k < spec.order; ++k) {
      EXPECT_NEAR(x(spec.order + k), laguerreStep(k, a, j * step_s), 1e-9) << "function " << k << " at step " << j;
      EXPECT_EQ(x(k), 0.0);                   // the x axis never moved
      EXPECT_EQ(x(2 * spec.order + k), 0.0);  // nor z
    }
  }
  basis.reset();
  EXPECT_TRUE(basis.state().isZero());
}

TEST(LinearDynamicsBasis, SineResponseIsTheTransferFunction) {
  LinearDynamicsBasisSpec spec;
  spec.pole_hz = 3.0;
  spec.order = 5;
  const double step_s = 1e-3, a = 2.0 * kPi * spec.pole_hz, w = 2.0 * kPi * 2.0;
  // The rate sampled at each step's middle and held over it (as the predictor steps): the steady
  // state differs from the continuous one by O((w h)^2 / 24) ~ 1e-5.
  std::vector<double> stamps, times;
  std::vector<Eigen::Vector3d> rates;
  for (int i = 0; i <= 6000; ++i) {
    stamps.push_back(i * 1e-3);
    rates.emplace_back(0.0, 0.0, std::sin(w * i * 1e-3));
  }
  for (double t = 4.0; t < 5.0; t += 0.01) times.push_back(t);
  const Eigen::MatrixXd states = linearDynamicsStates(spec, step_s, stamps, rates, times);
  double worst = 0.0;
  for (std::size_t q = 0; q < times.size(); ++q)
    for (int k = 0; k < spec.order; ++k) {
      // sin(w t) through H: |H| sin(w t + arg H).
      const std::complex<double> h = laguerreResponse(k, a, {0.0, w});
      const double expected = std::abs(h) * std::sin(w * times[q] + std::arg(h));
      worst = std::max(worst, std::abs(states(static_cast<long>(q), 2 * spec.order + k) - expected));
    }
  EXPECT_LT(worst, 2e-4);
}

TEST(LinearDynamicsBasis, TwoPoleBasisIsOrthonormal) {
  // For a white rate of unit spectral density the states' covariance is the identity: the
  // discrete Gramian sum_k Ad^k Bd Bd^T Ad^k^T / h, to O(p h).
  LinearDynamicsBasisSpec spec;
  spec.pole_hz = 1.0;
  spec.second_pole_hz = 6.0;
  spec.order = 6;
  const double step_s = 1e-3;
  const LinearDynamicsBasis basis(spec, step_s);
  Eigen::MatrixXd gramian = Eigen::MatrixXd::Zero(spec.order, spec.order);
  Eigen::VectorXd impulse = basis.discreteB();
  for (int k = 0; k < 20000; ++k) {
    gramian += impulse * impulse.transpose();
    impulse = basis.discreteA() * impulse;
  }
  gramian /= step_s;
  EXPECT_LT((gramian - Eigen::MatrixXd::Identity(spec.order, spec.order)).cwiseAbs().maxCoeff(), 0.03)
      << gramian;
  EXPECT_NEAR(basis.spec().poleRadS(1), 2.0 * kPi * 6.0, 1e-12);
  EXPECT_NEAR(basis.spec().poleRadS(2), 2.0 * kPi * 1.0, 1e-12);
}

// The simulator's constant-velocity Kalman stabiliser with nothing nonlinear in the way: a 4 kHz
// loop, a stroke it never reaches in these motions, a second-order actuator, no noise.
sim::StabiliserDesign kalmanDesign() {
  sim::StabiliserDesign d;
  d.estimator.kind = sim::EstimatorKind::kKalman;
  d.estimator.corner_hz = 0.5;
  d.mount.noise_rad_s = 0.0;
  d.stroke.x_positive_deg = d.stroke.x_negative_deg = d.stroke.y_positive_deg = d.stroke.y_negative_deg = 1.5;
  d.actuator.order = sim::ActuatorOrder::kSecond;
  d.actuator.bandwidth_hz = 40.0;
  d.actuator.damping = 0.7;
  EXPECT_EQ(d.validate(), "");
  return d;
}

struct Recording {
  std::vector<double> stamps_s;
  std::vector<Eigen::Vector3d> rates_rad_s;
  std::vector<Eigen::Vector2d> lens_focal;  // tan-angle
};

// A gyro at 200 Hz of gentle hand-held motion and the design's lens at its stamps.
Recording record(const sim::StabiliserDesign& design, std::uint32_t motion_seed, double duration_s) {
  sim::CameraMotionConfig config;
  config.shake_rms_rad_s = Eigen::Vector3d(0.06, 0.06, 0.03);
  config.shake_peak_rad_s = 0.2;
  config.pan_peak_rad_s = 0.05;
  const sim::CameraMotion motion(config, motion_seed, 0.0, duration_s);
  const double focal_px = 300.0;
  const int steps = static_cast<int>(duration_s * sim::kDesignPhysicsRateHz);
  const sim::LensShiftGrid lens = sim::runDesign(
      design, focal_px, 0.0, steps, [&motion](double t) { return motion.angularVelocity(t); }, nullptr);
  Recording r;
  for (double t = 0.0; t <= duration_s - 0.01; t += 0.005) {
    r.stamps_s.push_back(t);
    r.rates_rad_s.push_back(motion.angularVelocity(t));
    r.lens_focal.push_back(lens.at(t) / focal_px);
  }
  return r;
}

TEST(LinearDynamicsFit, RecoversTheSimulatorsKalmanStabiliser) {
  const sim::StabiliserDesign design = kalmanDesign();
  const double stroke_focal = std::tan(1.5 * kPi / 180.0);
  LinearDynamicsBasisSpec spec;
  // A slow pole for the estimator (0.5 Hz) and a fast one for the actuator (40 Hz): a Laguerre
  // basis at either alone needs far more functions (at 1 Hz x 8: R^2 0.9956; 2 Hz x 20: 0.99988).
  spec.pole_hz = 1.0;
  spec.second_pole_hz = 10.0;
  spec.order = 16;
  const double step_s = 1e-3;
  // Samples after the first 2 s (the Kalman gain settles from its initial covariance) and inside
  // 80 % of the stroke.
  auto samples = [&](const Recording& r, Eigen::MatrixXd* states, Eigen::MatrixXd* targets) {
    const Eigen::MatrixXd all = linearDynamicsStates(spec, step_s, r.stamps_s, r.rates_rad_s, r.stamps_s);
    std::vector<long> kept;
    for (std::size_t i = 0; i < r.stamps_s.size(); ++i)
      if (r.stamps_s[i] > 2.0 && r.lens_focal[i].cwiseAbs().maxCoeff() < 0.8 * stroke_focal)
        kept.push_back(static_cast<long>(i));
    states->resize(static_cast<long>(kept.size()), all.cols());
    targets->resize(static_cast<long>(kept.size()), 2);
    for (std::size_t i = 0; i < kept.size(); ++i) {
      states->row(static_cast<long>(i)) = all.row(kept[i]);
      targets->row(static_cast<long>(i)) = r.lens_focal[static_cast<std::size_t>(kept[i])].transpose();
    }
    return kept.size();
  };
  Eigen::MatrixXd train_x, train_y, test_x, test_y;
  const Recording training = record(design, 11, 20.0);
  const Recording held_out = record(design, 12, 20.0);
  ASSERT_GT(samples(training, &train_x, &train_y), 3000u);
  ASSERT_GT(samples(held_out, &test_x, &test_y), 3000u);
  LinearDynamicsFitReport report;
  const Eigen::MatrixXd c = fitLinearDynamicsCoefficients(train_x, train_y, Eigen::VectorXd(), 1e-9, &report);
  ASSERT_EQ(c.rows(), 2);
  ASSERT_EQ(c.cols(), 3 * spec.order);
  EXPECT_EQ(report.unexcited_states, 0);
  const Eigen::MatrixXd predicted = test_x * c.transpose();
  const Eigen::RowVector2d mean = test_y.colwise().mean();
  const double total = (test_y.rowwise() - mean).squaredNorm();
  const double r2 = 1.0 - (test_y - predicted).squaredNorm() / total;
  EXPECT_GT(r2, 0.999) << "held-out R^2";
  // The design's gyro is not turned against the camera: the roll functions carry almost nothing
  // of the predicted lens.
  const Eigen::MatrixXd from_roll =
      test_x.middleCols(2 * spec.order, spec.order) * c.middleCols(2 * spec.order, spec.order).transpose();
  EXPECT_LT(from_roll.norm(), 0.01 * predicted.norm());
}

TEST(LinearDynamicsFit, RefusesBadInputNamingIt) {
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(50, 4);
  const Eigen::MatrixXd y = Eigen::MatrixXd::Random(50, 2);
  auto message = [&](const Eigen::MatrixXd& s, const Eigen::MatrixXd& t, const Eigen::VectorXd& w, double ridge) {
    try {
      fitLinearDynamicsCoefficients(s, t, w, ridge);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(x, y.topRows(40), {}, 0.0).find("50 state rows but 40 target rows"), std::string::npos);
  EXPECT_NE(message(x, Eigen::MatrixXd::Zero(50, 3), {}, 0.0).find("2 columns"), std::string::npos);
  EXPECT_NE(message(x, y, Eigen::VectorXd::Ones(49), 0.0).find("49 weights"), std::string::npos);
  Eigen::MatrixXd bad = x;
  bad(17, 2) = std::nan("");
  EXPECT_NE(message(bad, y, {}, 0.0).find("state row 17 is not finite"), std::string::npos);
  Eigen::VectorXd w = Eigen::VectorXd::Ones(50);
  w(3) = -1.0;
  EXPECT_NE(message(x, y, w, 0.0).find("weight 3"), std::string::npos);
  EXPECT_NE(message(x, y, {}, -1.0).find("ridge"), std::string::npos);
  EXPECT_NE(message(x.topRows(3), y.topRows(3), {}, 0.0).find("3 weighted samples for 4"), std::string::npos);
  Eigen::MatrixXd dependent = x;
  dependent.col(3) = 2.0 * dependent.col(1);
  EXPECT_NE(message(dependent, y, {}, 0.0).find("rank-deficient"), std::string::npos);
  // With a ridge the same system is solved, and a component that never moved is counted.
  Eigen::MatrixXd idle = x;
  idle.col(2).setZero();
  LinearDynamicsFitReport report;
  const Eigen::MatrixXd c = fitLinearDynamicsCoefficients(idle, y, {}, 1e-6, &report);
  EXPECT_EQ(report.unexcited_states, 1);
  EXPECT_EQ(c(0, 2), 0.0);
  EXPECT_EQ(message(dependent, y, {}, 1e-6), "accepted");
  // The basis names a bad spec.
  LinearDynamicsBasisSpec spec;
  spec.order = 0;
  EXPECT_THROW(LinearDynamicsBasis(spec, 1e-3), std::invalid_argument);
  spec.order = 4;
  spec.pole_hz = 600.0;
  EXPECT_NE(spec.validate(1e-3).find("pole_hz"), std::string::npos);
}

TEST(LinearDynamicsFit, ExactCoefficientsFromNoiselessData) {
  // Targets made by known coefficients on the basis' own states come back (plain least squares).
  LinearDynamicsBasisSpec spec;
  spec.pole_hz = 1.5;
  spec.order = 4;
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> rates;
  for (int i = 0; i < 2000; ++i) {
    const double t = i * 0.005;
    stamps.push_back(t);
    rates.emplace_back(std::sin(3.1 * t) + 0.3 * std::sin(17.0 * t), std::cos(2.3 * t) * std::sin(7.0 * t),
                       0.2 * std::sin(11.0 * t + 1.0));
  }
  const Eigen::MatrixXd states = linearDynamicsStates(spec, 1e-3, stamps, rates, stamps);
  const Eigen::MatrixXd truth = Eigen::MatrixXd::Random(2, states.cols()) * 0.01;
  const Eigen::MatrixXd fitted = fitLinearDynamicsCoefficients(states, states * truth.transpose(), {}, 0.0);
  EXPECT_LT((fitted - truth).cwiseAbs().maxCoeff(), 1e-8);
}

}  // namespace
}  // namespace deep_ois
