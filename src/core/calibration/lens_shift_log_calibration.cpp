#include "deep_ois/core/calibration/lens_shift_log_calibration.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "deep_ois/core/common/so3_and_statistics.h"  // median
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"

namespace deep_ois {
namespace {

// One (pair, patch): the median image shift difference and the patch's camera-clock times.
struct Observation {
  double t_a_s = 0.0;
  double t_b_s = 0.0;
  Eigen::Matrix3d H;  // the gyro's K R K^-1 of the patch
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> tracks;  // undistorted (a, b)
  Eigen::Vector2d d_px;  // s_b - s_a seen by the tracks (median)
};

// s_b - s_a from the tracks given frame a's shift s_a: exactly, p_b = H (p_a - s_a) + s_b
// (K(s) = T(s) K), so s_b - s_a = p_b - H (p_a - s_a) - s_a per track; the median per axis.
// With s_a = 0 this is the first-order p_b - H p_a, off by (dH/dp - I) s_a.
Eigen::Vector2d shiftDifference(const Observation& o, const Eigen::Vector2d& s_a) {
  std::vector<double> dx, dy;
  for (const auto& [a, b] : o.tracks) {
    const Eigen::Vector2d r = b - (o.H * (a - s_a).homogeneous()).hnormalized() - s_a;
    dx.push_back(r.x());
    dy.push_back(r.y());
  }
  return {median(dx), median(dy)};
}

// The least-squares map A (d = A q) and its mean squared residual over `use` (all when empty).
struct MapFit {
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  double cost = std::numeric_limits<double>::infinity();
  bool ok = false;
};

MapFit fitMap(const std::vector<Eigen::Vector2d>& q, const std::vector<Eigen::Vector2d>& d,
              const std::vector<char>& use) {
  Eigen::Matrix2d QtQ = Eigen::Matrix2d::Zero(), QtD = Eigen::Matrix2d::Zero();
  int n = 0;
  for (std::size_t k = 0; k < q.size(); ++k) {
    if (!use[k]) continue;
    QtQ += q[k] * q[k].transpose();
    QtD += q[k] * d[k].transpose();
    ++n;
  }
  MapFit fit;
  if (n < 4 || std::abs(QtQ.determinant()) < 1e-12 * std::pow(QtQ.trace(), 2)) return fit;
  fit.A = QtQ.ldlt().solve(QtD).transpose();
  double sum = 0.0;
  for (std::size_t k = 0; k < q.size(); ++k) {
    if (use[k]) sum += (d[k] - fit.A * q[k]).squaredNorm();
  }
  fit.cost = sum / n;
  fit.ok = true;
  return fit;
}

}  // namespace

std::string LensShiftLogCalibrationOptions::validate() const {
  if (patch_count < 1) return "patch_count must be at least 1";
  if (!(max_abs_time_offset_s >= 0.0) || max_abs_time_offset_s > 10.0)
    return "max_abs_time_offset_s must be in [0, 10] s";
  if (!(search_step_s > 0.0)) return "search_step_s must be positive";
  if (!(max_gap_s > 0.0)) return "max_gap_s must be positive";
  if (min_tracks_per_patch < 1) return "min_tracks_per_patch must be at least 1";
  if (!(outlier_factor > 1.0)) return "outlier_factor must be > 1";
  return {};
}

LensShiftLogCalibration calibrateLensShiftLog(const CalibrationData& data,
                                              const CameraImuCalibration& calibration,
                                              const std::vector<LensShiftLogSample>& log,
                                              const LensShiftLogCalibrationOptions& options) {
  const std::string invalid = options.validate();
  if (!invalid.empty()) throw std::invalid_argument("lens-shift log calibration: " + invalid);
  LensShiftLogCalibration result;
  if (log.empty()) {
    result.problem = "the recording has no lens-shift log";
    return result;
  }

  // ---- Observations: per (pair, patch), the median of p_b - H_i p_a over its tracks. ----
  ImuSampleBuffer gyro(1e9);
  for (const ImuSample& sample : data.gyro) gyro.add(sample);
  IntegrationOptions integration;
  integration.gyro_bias_rad_s = calibration.gyro_bias_rad_s;
  RollingShutterConfig config;
  config.patch_count = options.patch_count;
  config.readout_time_s = calibration.readout_time_s;
  config.time_offset_s = calibration.time_offset_s;
  config.imu_to_camera_rotation = calibration.imu_to_camera_rotation;
  config.patch_time = PatchTimeReference::kPatchCentre;
  const CameraModel& camera = data.camera;
  std::vector<Observation> observations;
  for (const CalibrationPair& pair : data.pairs) {
    const double stamp_a = data.frame_stamps_s.at(pair.frame_a),
                 stamp_b = data.frame_stamps_s.at(pair.frame_b);
    const RollingShutterHomographies H =
        computeRollingShutterHomographies(gyro, integration, config, camera.K(), stamp_a, stamp_b);
    if (!H.ok()) continue;
    std::vector<Observation> patches(options.patch_count);
    for (const FeatureMatch& match : pair.matches) {
      const Eigen::Vector2d a_raw(match.point_a_px.x, match.point_a_px.y);
      const int patch = patchIndexOfRow(a_raw.y(), camera.height(), options.patch_count);
      patches[patch].tracks.emplace_back(
          camera.undistort(a_raw),
          camera.undistort(Eigen::Vector2d(match.point_b_px.x, match.point_b_px.y)));
    }
    for (int i = 0; i < options.patch_count; ++i) {
      Observation& o = patches[i];
      if (static_cast<int>(o.tracks.size()) < options.min_tracks_per_patch) continue;
      o.t_a_s = patchCameraTime(config, stamp_a, i);
      o.t_b_s = patchCameraTime(config, stamp_b, i);
      o.H = H.homographies[i];
      o.d_px = shiftDifference(o, Eigen::Vector2d::Zero());
      observations.push_back(std::move(o));
    }
  }

  // Keep the observations the log covers over the whole offset search range, so that every
  // candidate offset is judged on the same set.
  LensShiftLog raw(options.max_gap_s);
  for (const LensShiftLogSample& sample : log) raw.add(sample);  // refused samples: not used
  const double range = options.max_abs_time_offset_s;
  std::vector<Observation> usable;
  for (const Observation& o : observations) {
    if (raw.covers(o.t_a_s - range, o.t_a_s + range) &&
        raw.covers(o.t_b_s - range, o.t_b_s + range)) {
      usable.push_back(o);
    }
  }
  if (usable.size() < 20) {
    result.problem =
        "only " + std::to_string(usable.size()) + " of " + std::to_string(observations.size()) +
        " row-patch observations are covered by the lens-shift log over the whole offset search "
        "range (+-" +
        std::to_string(range) + " s); at least 20 are needed";
    return result;
  }
  // The fit of the convention to shift differences d (one per usable observation); `result`
  // holds the estimate, or the problem.
  auto fitConvention = [&](const std::vector<Eigen::Vector2d>& d) {
    LensShiftLogCalibration result;
    double signal = 0.0;
    for (const Eigen::Vector2d& di : d) signal += di.squaredNorm();
    result.lens_motion_rms_px = std::sqrt(signal / usable.size());

    // The logged differences for a candidate offset tau: camera time t is log stamp t - tau.
    auto loggedDifferences = [&](double tau) {
      LensShiftLogConvention identity;
      identity.time_offset_s = tau;
      raw.setConvention(identity);
      std::vector<Eigen::Vector2d> q;
      q.reserve(usable.size());
      for (const Observation& o : usable) q.push_back(raw.shiftAt(o.t_b_s) - raw.shiftAt(o.t_a_s));
      return q;
    };
    std::vector<char> all(usable.size(), 1);
    auto cost = [&](double tau, const std::vector<char>& use) {
      return fitMap(loggedDifferences(tau), d, use).cost;
    };

    // ---- Offset: grid search, outliers out at the best, then a parabola through the minimum. ----
    const int steps = static_cast<int>(std::floor(range / options.search_step_s));
    double best_tau = 0.0, best_cost = std::numeric_limits<double>::infinity();
    for (int k = -steps; k <= steps; ++k) {
      const double c = cost(k * options.search_step_s, all);
      if (c < best_cost) {
        best_cost = c;
        best_tau = k * options.search_step_s;
      }
    }
    if (!std::isfinite(best_cost)) {
      result.problem = "the logged lens shift does not vary: no offset or scale can be fitted";
      return result;
    }
    std::vector<char> inliers(usable.size(), 1);
    {
      const std::vector<Eigen::Vector2d> q = loggedDifferences(best_tau);
      const MapFit fit = fitMap(q, d, all);
      std::vector<double> residuals;
      for (std::size_t k = 0; k < q.size(); ++k) residuals.push_back((d[k] - fit.A * q[k]).norm());
      const double threshold = options.outlier_factor * std::max(median(residuals), 1e-6);
      for (std::size_t k = 0; k < q.size(); ++k) inliers[k] = residuals[k] <= threshold;
    }
    // Re-search near the grid minimum on the inliers, then refine with a parabola on a shrinking
    // bracket (the cost is smooth: linear interpolation of a dense log).
    double tau = best_tau;
    for (double h = options.search_step_s; h > 1e-6; h *= 0.5) {
      const double c0 = cost(tau - h, inliers), c1 = cost(tau, inliers),
                   c2 = cost(tau + h, inliers);
      if (c0 < c1 && c0 <= c2) {
        tau -= h;
      } else if (c2 < c1) {
        tau += h;
      } else {
        const double curvature = c0 - 2.0 * c1 + c2;
        if (curvature > 0.0) tau += std::clamp(0.5 * h * (c0 - c2) / curvature, -h, h);
      }
    }

    // ---- The map at that offset, snapped to scale x signed axis permutation. ----
    const std::vector<Eigen::Vector2d> q = loggedDifferences(tau);
    const MapFit fit = fitMap(q, d, inliers);
    if (!fit.ok) {
      result.problem = "the logged lens shift does not vary in both axes: the map cannot be fitted";
      return result;
    }
    result.fitted_map = fit.A;
    double best_score = -std::numeric_limits<double>::infinity();
    for (int swap = 0; swap < 2; ++swap) {
      for (double sx : {1.0, -1.0}) {
        for (double sy : {1.0, -1.0}) {
          LensShiftLogConvention c;
          c.swap_xy = swap == 1;
          c.sign_x = sx;
          c.sign_y = sy;
          const Eigen::Matrix2d P = c.matrix();  // scale 1
          // Least-squares scale for this P: A ~ scale P, scale = <A, P> / <P, P> (<P, P> = 2).
          const double score = (P.array() * fit.A.array()).sum() / 2.0;
          if (score > best_score) {
            best_score = score;
            result.convention = c;
          }
        }
      }
    }
    if (!(best_score > 0.0)) {
      result.problem = "the fitted map is degenerate (no positive scale)";
      return result;
    }
    result.convention.scale = best_score;
    result.convention.time_offset_s = tau;
    result.snap_error = (fit.A - result.convention.matrix()).norm() / fit.A.norm();
    result.observations = static_cast<int>(std::count(inliers.begin(), inliers.end(), 1));
    result.residual_rms_px = std::sqrt(fit.cost);
    if (result.lens_motion_rms_px < 3.0 * result.residual_rms_px) {
      result.problem = "the lens barely moved (shift differences " +
                       std::to_string(result.lens_motion_rms_px) + " px RMS against " +
                       std::to_string(result.residual_rms_px) +
                       " px residual): record hand-held shake with the OIS on";
      return result;
    }
    result.ok = true;
    return result;
  };

  // First pass: the first-order differences (s_a = 0). Second pass: the exact differences with
  // frame a's shift from the first estimate; this removes the (dH/dp - I) s_a term, which
  // grows with the lens' distance from the centre (it biased the scale by up to ~1 %).
  std::vector<Eigen::Vector2d> d;
  for (const Observation& o : usable) d.push_back(o.d_px);
  const LensShiftLogCalibration first = fitConvention(d);
  if (!first.ok) return first;
  LensShiftLog shifted(options.max_gap_s, first.convention);
  for (const LensShiftLogSample& sample : log) shifted.add(sample);
  d.clear();
  for (const Observation& o : usable) {
    d.push_back(shiftDifference(
        o, shifted.covers(o.t_a_s, o.t_a_s) ? shifted.shiftAt(o.t_a_s) : Eigen::Vector2d::Zero()));
  }
  return fitConvention(d);
}

}  // namespace deep_ois
