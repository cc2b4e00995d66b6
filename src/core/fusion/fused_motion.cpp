#include "deep_ois/core/fusion/fused_motion.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/common/printf_text.h"
#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {
namespace {

constexpr int kPerPatch = 5;  // rotation x, y, z (rad), shift x, y (px)

// One track on undistorted pixels, with the patch of its frame-a row.
struct Track {
  int patch = 0;
  Eigen::Vector2d a_px, b_px;
};

// Dehomogenised H a.
Eigen::Vector2d transfer(const Eigen::Matrix3d& H, const Eigen::Vector2d& a_px) {
  return (H * a_px.homogeneous()).hnormalized();
}

// The current correction of every patch: the rotation as a matrix (updated on the left, where the
// Jacobian is taken) and the shift.
struct Correction {
  std::vector<Eigen::Matrix3d> rotation;
  std::vector<Eigen::Vector2d> shift_px;

  explicit Correction(int patches)
      : rotation(patches, Eigen::Matrix3d::Identity()), shift_px(patches, Eigen::Vector2d::Zero()) {}
  // The 5 numbers of patch i (rotation vector, shift).
  Eigen::Matrix<double, kPerPatch, 1> parameters(int i) const {
    Eigen::Matrix<double, kPerPatch, 1> c;
    c << logSO3(rotation[i]), shift_px[i];
    return c;
  }
};

// The prediction of track `a_px` through patch correction (R, d) of prior P, and its Jacobian with
// respect to a left rotation increment and a shift increment (2 x 5).
Eigen::Vector2d predict(const Eigen::Matrix3d& K, const Eigen::Matrix3d& K_inv, const Eigen::Matrix3d& P,
                        const Eigen::Matrix3d& R, const Eigen::Vector2d& d_px, const Eigen::Vector2d& a_px,
                        Eigen::Matrix<double, 2, kPerPatch>* jacobian) {
  const Eigen::Vector3d u = R * (K_inv * (P * a_px.homogeneous()));
  const Eigen::Vector3d w = K * u;
  const Eigen::Vector2d p = w.head<2>() / w.z() + d_px;
  if (jacobian) {
    Eigen::Matrix<double, 2, 3> projection;
    projection << 1.0 / w.z(), 0.0, -w.x() / (w.z() * w.z()),  //
        0.0, 1.0 / w.z(), -w.y() / (w.z() * w.z());
    // K exp(e) u ~ K (u + e x u) = K (u - [u]x e).
    jacobian->leftCols<3>() = -projection * K * skew(u);
    jacobian->rightCols<2>().setIdentity();
  }
  return p;
}

// Mean and largest distance between two motions over a grid of the frame (raw pixels, each point
// through the homography of its own row patch), pixels.
void motionDifference(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& first,
                      const std::vector<Eigen::Matrix3d>& second, double* mean_px, double* max_px) {
  const int patches = static_cast<int>(first.size());
  const int columns = 16, rows = 4 * patches;
  double sum = 0.0, largest = 0.0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      const Eigen::Vector2d raw((c + 0.5) * camera.width() / columns - 0.5, (r + 0.5) * camera.height() / rows - 0.5);
      const Eigen::Vector2d a = camera.undistort(raw);
      const auto patch = static_cast<std::size_t>(patchIndexOfRow(raw.y(), camera.height(), patches));
      const double distance = (transfer(first[patch], a) - transfer(second[patch], a)).norm();
      sum += distance;
      largest = std::max(largest, distance);
    }
  }
  *mean_px = sum / (rows * columns);
  *max_px = largest;
}

FusedMotion priorKept(const MotionPrior& prior, FusedMotion fused, const std::string& why) {
  fused.homographies = prior.homographies;
  fused.refined = false;
  fused.corrections.assign(prior.homographies.size(), PatchCorrection());
  fused.mean_correction_px = fused.max_correction_px = 0.0;
  fused.reason = "prior kept: " + why;
  return fused;
}

}  // namespace

std::string FusionOptions::validate() const {
  std::ostringstream why;
  if (!(track_noise_px > 0.0) || !std::isfinite(track_noise_px))
    why << "track_noise_px must be positive (got " << track_noise_px << ")";
  else if (!(cauchy_px > 0.0) || !std::isfinite(cauchy_px)) why << "cauchy_px must be positive (got " << cauchy_px << ")";
  else if (!(outlier_px > cauchy_px) || !std::isfinite(outlier_px))
    why << "outlier_px (" << outlier_px << ") must exceed cauchy_px (" << cauchy_px << ")";
  else if (!(consistency_sigmas > 0.0) || !std::isfinite(consistency_sigmas))
    why << "consistency_sigmas must be positive (got " << consistency_sigmas << ")";
  else if (!(smoothness_px > 0.0) || !std::isfinite(smoothness_px))
    why << "smoothness_px must be positive (got " << smoothness_px << ")";
  else if (!(min_sigma_px > 0.0) || !std::isfinite(min_sigma_px))
    why << "min_sigma_px must be positive (got " << min_sigma_px << ")";
  else if (min_tracks < 1) why << "min_tracks must be at least 1 (got " << min_tracks << ")";
  else if (!(min_consistent_share >= 0.0 && min_consistent_share <= 1.0))
    why << "min_consistent_share must be in [0, 1] (got " << min_consistent_share << ")";
  else if (iterations < 1) why << "iterations must be at least 1 (got " << iterations << ")";
  return why.str();
}

Eigen::Matrix3d correctedHomography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& prior,
                                    const PatchCorrection& correction) {
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  T.topRightCorner<2, 1>() = correction.shift_px;
  const Eigen::Matrix3d H = T * K * expSO3(correction.rotation_rad) * K.inverse() * prior;
  return H / H(2, 2);
}

FusedMotion fuseMotion(const CameraModel& camera, const MotionPrior& prior, const std::vector<FeatureMatch>& matches,
                       const FusionOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("fuseMotion: " + problem);
  if (prior.homographies.empty()) throw std::invalid_argument("fuseMotion: the prior has no homographies (one per row patch)");
  for (std::size_t i = 0; i < prior.homographies.size(); ++i)
    if (!prior.homographies[i].allFinite())
      throw std::invalid_argument("fuseMotion: the prior's homography " + std::to_string(i) + " is not finite");
  if (!(prior.sigma_px > 0.0) || !std::isfinite(prior.sigma_px))
    throw std::invalid_argument("fuseMotion: the prior's sigma_px must be positive and finite (got " +
                                std::to_string(prior.sigma_px) + ")");
  const int patches = static_cast<int>(prior.homographies.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();

  FusedMotion fused;
  fused.tracks = static_cast<int>(matches.size());
  fused.prior_residual_px = fused.fused_residual_px = nan;

  // Undistorted in one call per frame (what per-frame code does: camera_model.h).
  std::vector<Eigen::Vector2d> a_px, b_px;
  std::vector<int> patch_of;
  for (const FeatureMatch& m : matches) {
    const Eigen::Vector2d a_raw(m.point_a_px.x, m.point_a_px.y), b_raw(m.point_b_px.x, m.point_b_px.y);
    if (!a_raw.allFinite() || !b_raw.allFinite()) continue;  // inconsistent with anything
    a_px.push_back(a_raw);
    b_px.push_back(b_raw);
    patch_of.push_back(patchIndexOfRow(a_raw.y(), camera.height(), patches));
  }
  camera.undistortPoints(a_px);
  camera.undistortPoints(b_px);
  std::vector<Track> all;
  std::vector<double> prior_error_px;
  for (std::size_t k = 0; k < a_px.size(); ++k) {
    const Track track{patch_of[k], a_px[k], b_px[k]};
    const double error = (transfer(prior.homographies[track.patch], track.a_px) - track.b_px).norm();
    if (!std::isfinite(error)) continue;
    all.push_back(track);
    prior_error_px.push_back(error);
  }
  // The prior's uncertainty on this pair: the given sigma, or less where the pair's own tracks show
  // the prior closer than that. The lower quartile of their transfer errors is 0.7585 sigma for a
  // 2-D Gaussian error of sigma per axis (the tracks' noise included), and is robust to a moving
  // object on up to three quarters of the tracks (the simulator's MF pairs often have more than half
  // of their tracks on the object). A sigma from recent checks holds their moving objects too.
  fused.sigma_px = prior.sigma_px;
  if (!prior_error_px.empty()) {
    std::vector<double> sorted = prior_error_px;
    const std::size_t quartile = sorted.size() / 4;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(quartile), sorted.end());
    const double scale_px = sorted[quartile] / 0.7585;
    const double pair_sigma_px =
        std::sqrt(std::max(0.0, scale_px * scale_px - options.track_noise_px * options.track_noise_px));
    fused.sigma_px = std::min(prior.sigma_px, std::max(options.min_sigma_px, pair_sigma_px));
  }
  // The consistency test against the prior: far beyond its uncertainty is not this motion.
  const double consistency_px = options.consistency_sigmas * std::hypot(fused.sigma_px, options.track_noise_px);
  std::vector<Track> tracks;
  for (std::size_t k = 0; k < all.size(); ++k)
    if (prior_error_px[k] <= consistency_px) tracks.push_back(all[k]);
  fused.consistent_tracks = static_cast<int>(tracks.size());
  if (fused.tracks == 0) return priorKept(prior, fused, "no tracks");
  if (fused.consistent_tracks < options.min_tracks) {
    return priorKept(prior, fused,
                     printfText("%d of %d tracks consistent with the prior (within %.2f px; needs %d)",
                                fused.consistent_tracks, fused.tracks, consistency_px, options.min_tracks));
  }
  const double share = static_cast<double>(fused.consistent_tracks) / fused.tracks;
  if (share < options.min_consistent_share) {
    return priorKept(prior, fused,
                     printfText("inconsistent tracks: %d of %d within %.2f px of the prior (%.0f %%; needs %.0f %%)",
                                fused.consistent_tracks, fused.tracks, consistency_px, 100.0 * share,
                                100.0 * options.min_consistent_share));
  }

  // Each component's image displacement per unit: the focal length for rotations about x and y, the
  // frame's RMS radius about its centre for the roll, 1 for the shift.
  const Eigen::Matrix3d& K = camera.K();
  const Eigen::Matrix3d& K_inv = camera.Kinv();
  const double focal_px = 0.5 * (K(0, 0) + K(1, 1));
  const double roll_radius_px =
      std::sqrt((static_cast<double>(camera.width()) * camera.width() + static_cast<double>(camera.height()) * camera.height()) / 12.0);
  const double pixels_per_unit[kPerPatch] = {focal_px, focal_px, roll_radius_px, 1.0, 1.0};

  const int unknowns = kPerPatch * patches;
  Correction correction(patches);
  std::vector<double> residual_px(tracks.size(), 0.0);
  const double track_weight = 1.0 / (options.track_noise_px * options.track_noise_px);
  const double prior_weight = 1.0 / (fused.sigma_px * fused.sigma_px);
  const double smooth_weight = 1.0 / (options.smoothness_px * options.smoothness_px);
  Eigen::VectorXd row(unknowns), target(1);
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    // In the second half of the passes, the tracks the fit cannot explain are out.
    const bool reject = iteration >= options.iterations / 2;
    // Cauchy weights from this pass's errors (the first pass: the prior's). A redescending loss: a
    // moving object's tracks, whose errors stay large, lose their say as the fit finds the rest.
    RobustRidgeRegression step_fit(unknowns, 1, RobustLoss::cauchy(options.cauchy_px));
    for (std::size_t t = 0; t < tracks.size(); ++t) {
      const Track& track = tracks[t];
      Eigen::Matrix<double, 2, kPerPatch> J;
      const Eigen::Vector2d r = track.b_px - predict(K, K_inv, prior.homographies[track.patch],
                                                     correction.rotation[track.patch],
                                                     correction.shift_px[track.patch], track.a_px, &J);
      residual_px[t] = r.norm();
      if (reject && residual_px[t] > options.outlier_px) continue;  // out
      for (int axis = 0; axis < 2; ++axis) {
        row.setZero();
        row.segment<kPerPatch>(kPerPatch * track.patch) = J.row(axis).transpose();
        target(0) = r(axis);
        step_fit.add(row, target, track_weight, residual_px[t]);
      }
    }
    // The prior (no correction) and the smoothness between neighbouring patches, in pixels:
    // outside the loss (reference residual 0, weight 1).
    for (int i = 0; i < patches; ++i) {
      const Eigen::Matrix<double, kPerPatch, 1> c = correction.parameters(i);
      for (int j = 0; j < kPerPatch; ++j) {
        row.setZero();
        row(kPerPatch * i + j) = pixels_per_unit[j];
        target(0) = -pixels_per_unit[j] * c(j);
        step_fit.add(row, target, prior_weight, 0.0);
      }
    }
    for (int i = 0; i + 1 < patches; ++i) {
      const Eigen::Matrix<double, kPerPatch, 1> difference = correction.parameters(i) - correction.parameters(i + 1);
      for (int j = 0; j < kPerPatch; ++j) {
        row.setZero();
        row(kPerPatch * i + j) = pixels_per_unit[j];
        row(kPerPatch * (i + 1) + j) = -pixels_per_unit[j];
        target(0) = -pixels_per_unit[j] * difference(j);
        step_fit.add(row, target, smooth_weight, 0.0);
      }
    }
    // The package's robust ridge regression, without a ridge: the prior rows make it full rank.
    Eigen::MatrixXd solution;
    if (!step_fit.solve(0.0, &solution)) break;  // not finite: the last finite correction stands
    const Eigen::VectorXd step = solution.col(0);
    for (int i = 0; i < patches; ++i) {
      correction.rotation[i] = expSO3(step.segment<3>(kPerPatch * i)) * correction.rotation[i];
      correction.shift_px[i] += step.segment<2>(kPerPatch * i + 3);
    }
  }

  // The final inliers and their errors under the prior and the fused motion.
  fused.corrections.assign(patches, PatchCorrection());
  std::vector<Eigen::Matrix3d> homographies(patches);
  for (int i = 0; i < patches; ++i) {
    fused.corrections[i].rotation_rad = logSO3(correction.rotation[i]);
    fused.corrections[i].shift_px = correction.shift_px[i];
    homographies[i] = correctedHomography(K, prior.homographies[i], fused.corrections[i]);
  }
  double prior_sum = 0.0, fused_sum = 0.0;
  for (const Track& track : tracks) {
    const double error = (transfer(homographies[track.patch], track.a_px) - track.b_px).norm();
    if (!(error <= options.outlier_px)) continue;
    fused_sum += error;
    prior_sum += (transfer(prior.homographies[track.patch], track.a_px) - track.b_px).norm();
    ++fused.inliers;
    ++fused.corrections[track.patch].inliers;
  }
  if (fused.inliers < options.min_tracks) {
    return priorKept(prior, fused,
                     printfText("%d tracks fit within %.2f px (of %d consistent; needs %d)", fused.inliers,
                                options.outlier_px, fused.consistent_tracks, options.min_tracks));
  }
  fused.prior_residual_px = prior_sum / fused.inliers;
  fused.fused_residual_px = fused_sum / fused.inliers;
  if (!(fused.fused_residual_px < fused.prior_residual_px)) {
    return priorKept(prior, fused,
                     printfText("the tracks do not improve on it (%.3f px fused, %.3f px prior, %d tracks)",
                                fused.fused_residual_px, fused.prior_residual_px, fused.inliers));
  }
  fused.homographies = std::move(homographies);
  fused.refined = true;
  motionDifference(camera, fused.homographies, prior.homographies, &fused.mean_correction_px, &fused.max_correction_px);
  fused.reason = printfText("refined on %d tracks, mean correction %.2f px (largest %.2f px; residual %.3f -> %.3f px)",
                            fused.inliers, fused.mean_correction_px, fused.max_correction_px,
                            fused.prior_residual_px, fused.fused_residual_px);
  return fused;
}

}  // namespace deep_ois
