#include "deep_ois/core/ois_lens_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

namespace deep_ois {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Fit parameters: gain (2), log corner, delay, log stroke (the centre is part of the drift).
constexpr int kFitParameters = 5;
using FitVector = Eigen::Matrix<double, kFitParameters, 1>;

OisLensModel modelOf(const FitVector& p) {
  OisLensModel model;
  model.gain_px_per_rad = p.head<2>();
  model.centring_corner_hz = std::exp(p(2));
  model.delay_s = p(3);
  model.stroke_px = std::exp(p(4));
  return model;
}

FitVector vectorOf(const OisLensModel& model) {
  FitVector p;
  p << model.gain_px_per_rad, std::log(model.centring_corner_hz), model.delay_s, std::log(model.stroke_px);
  return p;
}

// Residuals (prediction - sample) of every sample, x then y, after each axis' slow drift (a
// polynomial of time of order kDriftOrder, its constant the lens centre) is fitted out; the
// model's own centre is ignored. With `centre`, the drift's mean over the samples.
static double kDriftKnotSamples = getenv("EXP_KNOT") ? atof(getenv("EXP_KNOT")) : 500.0;

Eigen::VectorXd residualsOf(const OisLensModel& model, const std::vector<Eigen::Vector3d>& rates, double step_s,
                            const std::vector<OisLensSample>& samples, Eigen::Vector2d* centre = nullptr) {
  OisLensModel centred = model;
  centred.centre_px.setZero();
  const std::vector<Eigen::Vector2d> predicted = predictOisLensShift(centred, rates, step_s);
  const std::size_t n = samples.size();
  double first = samples.front().index, last = samples.front().index;
  for (const OisLensSample& sample : samples) {
    first = std::min(first, sample.index);
    last = std::max(last, sample.index);
  }
  // Piecewise linear in time, knots every kDriftKnotSamples.
  const int knots = static_cast<int>(std::ceil((last - first) / kDriftKnotSamples)) + 1;
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(n, knots);
  for (std::size_t i = 0; i < n; ++i) {
    const double u = (samples[i].index - first) / kDriftKnotSamples;
    const int k = std::min(static_cast<int>(u), knots - 2 < 0 ? 0 : knots - 2);
    const double f = u - k;
    T(i, k) += 1.0 - f;
    if (k + 1 < knots) T(i, k + 1) += f;
  }
  Eigen::MatrixXd D(n, 2);
  for (std::size_t i = 0; i < n; ++i) {
    D.row(i) = (interpolateLensShift(predicted, samples[i].index - model.delay_s / step_s) - samples[i].shift_px)
                   .transpose();
  }
  const Eigen::MatrixXd drift = T.colPivHouseholderQr().solve(D);
  const Eigen::MatrixXd left = D - T * drift;
  if (centre) *centre = -(T * drift).colwise().mean().transpose();
  Eigen::VectorXd r(2 * n);
  for (std::size_t i = 0; i < n; ++i) r.segment<2>(2 * i) = left.row(i).transpose();
  return r;
}

}  // namespace

std::vector<Eigen::Vector2d> predictOisLensShift(const OisLensModel& model,
                                                 const std::vector<Eigen::Vector3d>& camera_rates_rad_s,
                                                 double step_s) {
  // Without the delay: the callers shift the sample index by delay / step (the delay is a
  // fitted parameter, and a fractional index keeps it continuous).
  std::vector<Eigen::Vector2d> shifts(camera_rates_rad_s.size(), model.centre_px);
  const double wc = 2.0 * kPi * std::max(model.centring_corner_hz, 0.0);
  const double decay = std::exp(-wc * step_s);
  // Exact for a rate that is constant over the step (its mean).
  const double rate_weight = wc > 0.0 ? -std::expm1(-wc * step_s) / wc : step_s;
  Eigen::Vector2d theta = Eigen::Vector2d::Zero();  // (pan about y, tilt about x), rad
  for (std::size_t i = 0; i < camera_rates_rad_s.size(); ++i) {
    if (i > 0) {
      const Eigen::Vector3d mean = 0.5 * (camera_rates_rad_s[i - 1] + camera_rates_rad_s[i]);
      theta = decay * theta + rate_weight * Eigen::Vector2d(mean.y(), mean.x());
    }
    const Eigen::Vector2d command = model.gain_px_per_rad.cwiseProduct(theta);
    shifts[i] = model.centre_px + command.cwiseMax(-model.stroke_px).cwiseMin(model.stroke_px);
  }
  return shifts;
}

Eigen::Vector2d interpolateLensShift(const std::vector<Eigen::Vector2d>& shifts_px, double index) {
  if (shifts_px.empty()) return Eigen::Vector2d::Zero();
  const double last = static_cast<double>(shifts_px.size() - 1);
  const double i = std::clamp(index, 0.0, last);
  const std::size_t k = std::min(static_cast<std::size_t>(i), shifts_px.size() - 1);
  if (k + 1 >= shifts_px.size()) return shifts_px.back();
  const double f = i - static_cast<double>(k);
  return (1.0 - f) * shifts_px[k] + f * shifts_px[k + 1];
}

OisLensFit fitOisLensModel(const std::vector<Eigen::Vector3d>& camera_rates_rad_s, double step_s,
                           const std::vector<OisLensSample>& samples) {
  if (samples.size() < 10) throw std::invalid_argument("OIS lens fit: needs at least 10 lens-shift samples");
  if (!(step_s > 0.0)) throw std::invalid_argument("OIS lens fit: the rate step must be positive");
  OisLensFit fit;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const OisLensSample& sample : samples) mean += sample.shift_px;
  mean /= static_cast<double>(samples.size());
  double spread = 0.0;
  for (const OisLensSample& sample : samples) spread += (sample.shift_px - mean).squaredNorm();
  fit.rms_shift_px = std::sqrt(spread / samples.size());

  // Start: without a stroke the shift is linear in gain and centre; the best of a few corners.
  double best_cost = std::numeric_limits<double>::infinity();
  for (double corner_hz : {0.15, 0.3, 0.6, 1.2, 2.4}) {
    OisLensModel unit;
    unit.centring_corner_hz = corner_hz;
    unit.gain_px_per_rad = Eigen::Vector2d::Ones();
    const std::vector<Eigen::Vector2d> angles = predictOisLensShift(unit, camera_rates_rad_s, step_s);
    OisLensModel model = unit;
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::MatrixXd A(samples.size(), 2);
      Eigen::VectorXd b(samples.size());
      for (std::size_t i = 0; i < samples.size(); ++i) {
        A(i, 0) = interpolateLensShift(angles, samples[i].index - unit.delay_s / step_s)(axis);
        A(i, 1) = 1.0;
        b(i) = samples[i].shift_px(axis);
      }
      const Eigen::Vector2d solution = A.colPivHouseholderQr().solve(b);
      model.gain_px_per_rad(axis) = solution(0);
      model.centre_px(axis) = solution(1);
    }
    // The stroke starts at the largest excursion the samples show.
    double excursion = 0.0;
    for (const OisLensSample& sample : samples) {
      excursion = std::max(excursion, (sample.shift_px - model.centre_px).cwiseAbs().maxCoeff());
    }
    model.stroke_px = std::max(excursion, 0.1);
    const double cost = residualsOf(model, camera_rates_rad_s, step_s, samples).squaredNorm();
    if (cost < best_cost) {
      best_cost = cost;
      fit.model = model;
    }
  }

  // Levenberg-Marquardt, forward-difference Jacobian (each column one prediction over the rates).
  FitVector p = vectorOf(fit.model);
  Eigen::VectorXd r = residualsOf(fit.model, camera_rates_rad_s, step_s, samples);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  const FitVector h = (FitVector() << 1.0, 1.0, 1e-3, 1e-4, 1e-3).finished();
  for (int iteration = 0; iteration < 30; ++iteration) {
    Eigen::MatrixXd J(r.size(), kFitParameters);
    for (int k = 0; k < kFitParameters; ++k) {
      FitVector q = p;
      q(k) += h(k);
      J.col(k) = (residualsOf(modelOf(q), camera_rates_rad_s, step_s, samples) - r) / h(k);
    }
    const Eigen::Matrix<double, kFitParameters, kFitParameters> JtJ = J.transpose() * J;
    const FitVector Jtr = J.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 8 && !improved; ++attempt) {
      Eigen::Matrix<double, kFitParameters, kFitParameters> damped = JtJ;
      damped.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const FitVector step = damped.ldlt().solve(-Jtr);
      FitVector candidate = p + step;
      candidate(2) = std::clamp(candidate(2), std::log(0.01), std::log(20.0));  // corner 0.01..20 Hz
      candidate(3) = std::clamp(candidate(3), -0.02, 0.05);                    // delay -20..50 ms
      const Eigen::VectorXd trial = residualsOf(modelOf(candidate), camera_rates_rad_s, step_s, samples);
      if (trial.squaredNorm() < cost) {
        const double gain = cost - trial.squaredNorm();
        p = candidate;
        r = trial;
        cost = trial.squaredNorm();
        lambda = std::max(lambda * 0.2, 1e-9);
        improved = true;
        if (gain < 1e-9 * cost) iteration = 30;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  fit.model = modelOf(p);
  residualsOf(fit.model, camera_rates_rad_s, step_s, samples, &fit.model.centre_px);
  fit.rms_residual_px = std::sqrt(cost / samples.size());
  return fit;
}

}  // namespace deep_ois
