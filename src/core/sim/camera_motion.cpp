#include "deep_ois/core/sim/camera_motion.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;
constexpr int kShakeComponentsPerAxis = 40;
constexpr int kTranslationComponentsPerAxis = 12;
// Translation band: [high / kTranslationBandRatio, high]; wobble slower than that is a walk,
// not a hand-held wobble.
constexpr double kTranslationBandRatio = 10.0;
// The shake limiter is the identity below this fraction of shake_peak_rad_s.
constexpr double kLimiterKnee = 0.8;
// The grid must resolve the fastest shake component with many steps per period.
constexpr double kMinStepsPerShakePeriod = 10.0;

// Sum of amplitude * sin(2 pi f t + phase) over a series (a template: the component type is
// private to CameraMotion).
template <typename Series>
double sinusoidSum(const Series& series, double t_s) {
  double sum = 0.0;
  for (const auto& s : series) {
    sum += s.amplitude * std::sin(kTwoPi * s.frequency_hz * t_s + s.phase_rad);
  }
  return sum;
}

// Smooth magnitude limiter: identity up to the knee, then a tanh that approaches `peak` without
// reaching it; C1 at the knee, direction preserved. Returns the scale factor g(r) / r and, in
// `slope`, g'(r).
double limiterScale(double r, double peak, double* slope) {
  const double knee = kLimiterKnee * peak;
  if (r <= knee) {
    *slope = 1.0;
    return 1.0;
  }
  const double span = peak - knee;
  const double th = std::tanh((r - knee) / span);
  *slope = 1.0 - th * th;
  return (knee + span * th) / r;
}

}  // namespace

std::string CameraMotionConfig::validate() const {
  std::ostringstream why;
  auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
  auto nonNegative = [](double x) { return std::isfinite(x) && x >= 0.0; };
  if (!positive(shake_band_low_hz)) {
    why << "shake_band_low_hz: must be positive (got " << shake_band_low_hz << " Hz)";
  } else if (!std::isfinite(shake_band_high_hz) || shake_band_high_hz < shake_band_low_hz) {
    why << "shake_band_high_hz: must be at least shake_band_low_hz (got " << shake_band_high_hz
        << " Hz < " << shake_band_low_hz << " Hz)";
  } else if (!nonNegative(shake_rms_rad_s.x()) || !nonNegative(shake_rms_rad_s.y()) ||
             !nonNegative(shake_rms_rad_s.z())) {
    why << "shake_rms_rad_s: must be three non-negative rates (got " << shake_rms_rad_s.transpose()
        << ")";
  } else if (!positive(shake_peak_rad_s)) {
    why << "shake_peak_rad_s: must be positive (got " << shake_peak_rad_s << ")";
  } else if (!nonNegative(pan_peak_rad_s)) {
    why << "pan_peak_rad_s: must be non-negative (got " << pan_peak_rad_s << ")";
  } else if (!positive(pan_period_s)) {
    why << "pan_period_s: must be positive (got " << pan_period_s << " s)";
  } else if (!nonNegative(translation_rms_m)) {
    why << "translation_rms_m: must be non-negative (got " << translation_rms_m << " m)";
  } else if (!positive(translation_band_high_hz)) {
    why << "translation_band_high_hz: must be positive (got " << translation_band_high_hz << " Hz)";
  } else if (!positive(integration_rate_hz) ||
             integration_rate_hz < kMinStepsPerShakePeriod * shake_band_high_hz) {
    why << "integration_rate_hz: must be at least " << kMinStepsPerShakePeriod
        << " x shake_band_high_hz (got " << integration_rate_hz << " Hz)";
  }
  return why.str();
}

CameraMotion::CameraMotion(const CameraMotionConfig& config, std::uint32_t seed, double start_s,
                           double end_s)
    : config_(config), start_s_(start_s), end_s_(end_s) {
  const std::string problem = config_.validate();
  if (!problem.empty()) throw std::invalid_argument("camera motion: " + problem);
  if (!std::isfinite(start_s) || !std::isfinite(end_s) || !(end_s > start_s)) {
    std::ostringstream why;
    why << "camera motion: the time span must be finite with end > start (got [" << start_s << ", "
        << end_s << "] s)";
    throw std::invalid_argument(why.str());
  }

  // Random-phase components on stratified frequencies: component i lies in the i-th of `count`
  // equal sub-bands of [low, high], so the band is covered evenly and no two frequencies
  // coincide by chance (which would make the RMS realised over a short span wander). Equal
  // amplitudes give an RMS of `rms` (sum of amplitude^2 / 2 = rms^2): a flat rate spectrum.
  auto drawSeries = [](std::mt19937& rng, int count, double low_hz, double high_hz, double rms) {
    std::vector<Sinusoid> series;
    series.reserve(count);
    const double amplitude = rms * std::sqrt(2.0 / count);
    for (int i = 0; i < count; ++i) {
      const double frequency = low_hz + (high_hz - low_hz) * (i + uniform01(rng)) / count;
      series.push_back({amplitude, frequency, kTwoPi * uniform01(rng)});
    }
    // Drawn regardless, so that the other axes' components do not depend on this one's RMS.
    if (amplitude == 0.0) series.clear();
    return series;
  };
  std::mt19937 shake_rng = streamGenerator(seed, 0);
  for (int axis = 0; axis < 3; ++axis) {
    shake_[axis] = drawSeries(shake_rng, kShakeComponentsPerAxis, config_.shake_band_low_hz,
                              config_.shake_band_high_hz, config_.shake_rms_rad_s[axis]);
  }

  // One pan per period, starting at start_s: peak rate of random direction in the pitch/yaw
  // plane and magnitude in [0.3, 1] x pan_peak_rad_s.
  std::mt19937 pan_rng = streamGenerator(seed, 1);
  const int pan_count = static_cast<int>(std::ceil((end_s_ - start_s_) / config_.pan_period_s)) + 1;
  for (int k = 0; k < pan_count; ++k) {
    const double magnitude = config_.pan_peak_rad_s * (0.3 + 0.7 * uniform01(pan_rng));
    const double direction = kTwoPi * uniform01(pan_rng);
    pans_.emplace_back(magnitude * std::sin(direction), magnitude * std::cos(direction));
  }

  std::mt19937 translation_rng = streamGenerator(seed, 2);
  const double high = config_.translation_band_high_hz;
  for (int axis = 0; axis < 3; ++axis) {
    translation_[axis] = drawSeries(translation_rng, kTranslationComponentsPerAxis,
                                    high / kTranslationBandRatio, high, config_.translation_rms_m);
  }

  const double anchor_s = std::clamp(0.0, start_s_, end_s_);
  centre_anchor_m_ = translationSeries(anchor_s);
  integrateOrientation();
}

Eigen::Vector3d CameraMotion::unlimitedShake(double t_s) const {
  return Eigen::Vector3d(sinusoidSum(shake_[0], t_s), sinusoidSum(shake_[1], t_s),
                         sinusoidSum(shake_[2], t_s));
}

// Pan k covers [start + k P, start + (k+1) P] with rate peak_k * sin^2(pi (t - t_k) / P): zero
// rate and zero acceleration at both ends, so consecutive pans join smoothly; the peak of each
// is |peak_k| <= pan_peak_rad_s. Pitch is about camera x, yaw about camera y.
Eigen::Vector3d CameraMotion::panRate(double t_s) const {
  const double phase = (t_s - start_s_) / config_.pan_period_s;
  const double k = std::floor(phase);
  if (k < 0.0 || k >= static_cast<double>(pans_.size())) return Eigen::Vector3d::Zero();
  const double bump = std::sin(kPi * (phase - k));
  const Eigen::Vector2d& peak = pans_[static_cast<std::size_t>(k)];
  return Eigen::Vector3d(peak.x(), peak.y(), 0.0) * (bump * bump);
}

Eigen::Vector3d CameraMotion::translationSeries(double t_s) const {
  return Eigen::Vector3d(sinusoidSum(translation_[0], t_s), sinusoidSum(translation_[1], t_s),
                         sinusoidSum(translation_[2], t_s));
}

Eigen::Vector3d CameraMotion::angularVelocity(double t_s) const {
  const Eigen::Vector3d shake = unlimitedShake(t_s);
  double slope;
  return shake * limiterScale(shake.norm(), config_.shake_peak_rad_s, &slope) + panRate(t_s);
}

Eigen::Vector3d CameraMotion::linearAcceleration(double t_s) const {
  Eigen::Vector3d a;
  for (int axis = 0; axis < 3; ++axis) {
    double sum = 0.0;
    for (const auto& s : translation_[axis]) {
      const double omega = kTwoPi * s.frequency_hz;
      sum -= omega * omega * s.amplitude * std::sin(omega * t_s + s.phase_rad);
    }
    a[axis] = sum;
  }
  return a;
}

// Grid step k -> k+1 uses the body rate w and its time derivative w' at both grid points
// (closed form). The step's rotation vector is the second-order Magnus vector: the rate integral
// by the corrected trapezoid h/2 (w0 + w1) + h^2/12 (w0' - w1') (error h^5), plus the coning
// term h^2/12 w0 x w1 (the core integrator's term, whose error is also h^5 for a smooth rate);
// R(k+1) = R(k) exp(Omega). Fourth order overall: over 12 s at 4 kHz the drift is ~1e-12 rad.
void CameraMotion::integrateOrientation() {
  const double span = end_s_ - start_s_;
  const int steps = std::max(1, static_cast<int>(std::ceil(span * config_.integration_rate_hz)));
  grid_step_s_ = span / steps;
  const double h = grid_step_s_;

  // Unlimited shake and its derivative at every grid point. Each component's phasor advances by
  // a fixed rotation per step (no sin/cos per step: 10x faster), re-synchronised with the closed
  // form every kResync steps so rounding cannot accumulate beyond ~1e-14.
  constexpr int kResync = 256;
  std::vector<Eigen::Vector3d> shake(steps + 1, Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> shake_dot(steps + 1, Eigen::Vector3d::Zero());
  for (int axis = 0; axis < 3; ++axis) {
    for (const auto& s : shake_[axis]) {
      const double omega = kTwoPi * s.frequency_hz;
      const double step_cos = std::cos(omega * h), step_sin = std::sin(omega * h);
      double c = 0.0, sn = 0.0;
      for (int k = 0; k <= steps; ++k) {
        if (k % kResync == 0) {
          const double angle = omega * (start_s_ + k * h) + s.phase_rad;
          c = std::cos(angle);
          sn = std::sin(angle);
        } else {
          const double next_c = c * step_cos - sn * step_sin;
          sn = sn * step_cos + c * step_sin;
          c = next_c;
        }
        shake[k][axis] += s.amplitude * sn;
        shake_dot[k][axis] += s.amplitude * omega * c;
      }
    }
  }

  // Limited shake plus pans, and the derivative by the limiter's chain rule.
  std::vector<Eigen::Vector3d> rate_dot(steps + 1);
  rate_grid_.resize(steps + 1);
  for (int k = 0; k <= steps; ++k) {
    const double t = start_s_ + k * h;
    const double r = shake[k].norm();
    double slope;
    const double scale = limiterScale(r, config_.shake_peak_rad_s, &slope);
    Eigen::Vector3d limited_dot = scale * shake_dot[k];
    if (scale < 1.0) {
      // d/dt (s g(r) / r) = s' g / r + s (g' - g / r) r' / r, with r' = s . s' / r.
      const double r_dot = shake[k].dot(shake_dot[k]) / r;
      limited_dot += shake[k] * ((slope - scale) * r_dot / r);
    }
    // Pan derivative: peak * pi / P * sin(2 pi (t - t_k) / P).
    const double phase = (t - start_s_) / config_.pan_period_s;
    const double pan_k = std::floor(phase);
    Eigen::Vector3d pan_dot = Eigen::Vector3d::Zero();
    if (pan_k >= 0.0 && pan_k < static_cast<double>(pans_.size())) {
      const Eigen::Vector2d& peak = pans_[static_cast<std::size_t>(pan_k)];
      pan_dot.head<2>() = peak * (kPi / config_.pan_period_s * std::sin(kTwoPi * (phase - pan_k)));
    }
    rate_grid_[k] = scale * shake[k] + panRate(t);
    rate_dot[k] = limited_dot + pan_dot;
  }

  step_rotation_grid_.resize(steps);
  orientation_grid_.resize(steps + 1);
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  orientation_grid_[0] = q.coeffs();
  for (int k = 0; k < steps; ++k) {
    const Eigen::Vector3d& w0 = rate_grid_[k];
    const Eigen::Vector3d& w1 = rate_grid_[k + 1];
    const Eigen::Vector3d omega =
        0.5 * h * (w0 + w1) + (h * h / 12.0) * (rate_dot[k] - rate_dot[k + 1] + w0.cross(w1));
    step_rotation_grid_[k] = omega;
    const double angle = omega.norm();
    if (angle > 0.0) {
      q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))).normalized();
    }
    orientation_grid_[k + 1] = q.coeffs();
  }

  // Re-anchor: a constant world rotation on the left keeps dR/dt = R [w]x and puts the reference
  // orientation (optical axis along world +x, camera x along world -y, camera y along -z) at the
  // anchor time.
  Eigen::Matrix3d reference;
  reference << 0.0, 0.0, 1.0,  //
      -1.0, 0.0, 0.0,          //
      0.0, -1.0, 0.0;
  const double anchor_s = std::clamp(0.0, start_s_, end_s_);
  const Eigen::Quaterniond correction(reference * pose(anchor_s).R_world_cam.transpose());
  for (auto& coeffs : orientation_grid_) {
    coeffs = (correction * Eigen::Quaterniond(coeffs)).normalized().coeffs();
  }
}

// Cubic Hermite interpolation of the rotation vector phi(tau) of R(k)^T R(t): phi(0) = 0,
// phi'(0) = w_k, phi(h) = Omega_k, phi'(h) = J_r(Omega)^-1 w_{k+1} ~ w_{k+1} + Omega x w_{k+1} / 2
// (R = R_k exp(phi) gives w = J_r(phi) phi'). Error ~h^4: 1e-12 rad, where slerp would be off
// by h^2 |w'| / 8 ~ 1e-6 rad mid-step.
CameraPose CameraMotion::pose(double t_s) const {
  const double t = std::clamp(t_s, start_s_, end_s_);
  const int steps = static_cast<int>(step_rotation_grid_.size());
  const int k =
      std::clamp(static_cast<int>(std::floor((t - start_s_) / grid_step_s_)), 0, steps - 1);
  const double h = grid_step_s_;
  const double s = std::clamp((t - start_s_ - k * h) / h, 0.0, 1.0);
  const Eigen::Vector3d& omega = step_rotation_grid_[k];
  const Eigen::Vector3d& w1 = rate_grid_[k + 1];
  const Eigen::Vector3d slope0 = rate_grid_[k];
  const Eigen::Vector3d slope1 = w1 + 0.5 * omega.cross(w1);
  const double s2 = s * s, s3 = s2 * s;
  const Eigen::Vector3d phi =
      (s3 - 2.0 * s2 + s) * h * slope0 + (3.0 * s2 - 2.0 * s3) * omega + (s3 - s2) * h * slope1;
  CameraPose result;
  result.R_world_cam = Eigen::Quaterniond(orientation_grid_[k]).toRotationMatrix() * expSO3(phi);
  result.centre_world_m = translationSeries(t) - centre_anchor_m_;
  return result;
}

}  // namespace sim
}  // namespace deep_ois
