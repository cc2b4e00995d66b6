#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {
namespace {

// One track on undistorted pixels, with the patch of its frame-a row.
struct Track {
  int pair = 0;
  int patch = 0;
  Eigen::Vector2d a_px;
  Eigen::Vector2d b_px;
};

// Index of the x coordinate of lens position (frame, patch); y follows it.
int unknownIndex(int frame, int patch, int patch_count) { return 2 * (frame * patch_count + patch); }

// Dehomogenised H q and its 2x2 Jacobian with respect to q.
Eigen::Vector2d applyHomography(const Eigen::Matrix3d& H, const Eigen::Vector2d& q,
                                Eigen::Matrix2d* jacobian) {
  const Eigen::Vector3d w = H * q.homogeneous();
  const Eigen::Vector2d h = w.head<2>() / w.z();
  if (jacobian) {
    *jacobian = (H.topLeftCorner<2, 2>() - h * H.block<1, 2>(2, 0)) / w.z();
  }
  return h;
}

}  // namespace

std::string LensShiftOptions::validate() const {
  std::ostringstream why;
  if (patch_count < 1) why << "patch_count must be >= 1 (got " << patch_count << ")";
  else if (!(readout_time_s >= 0.0)) why << "readout_time_s must be >= 0";
  else if (!(lens_random_walk_px_per_sqrt_s > 0.0)) why << "lens_random_walk_px_per_sqrt_s must be > 0";
  else if (!(centre_prior_px > 0.0)) why << "centre_prior_px must be > 0";
  else if (!(huber_px > 0.0)) why << "huber_px must be > 0";
  else if (!(outlier_px > huber_px)) why << "outlier_px must exceed huber_px";
  else if (iterations < 1) why << "iterations must be >= 1";
  return why.str();
}

LensShiftTrajectory estimateLensShiftTrajectory(const CameraModel& camera,
                                                const std::vector<double>& frame_stamps_s,
                                                const std::vector<LensShiftPairObservation>& pairs,
                                                const LensShiftOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("estimateLensShiftTrajectory: " + problem);
  const int frame_count = static_cast<int>(frame_stamps_s.size());
  for (int f = 1; f < frame_count; ++f) {
    if (!(frame_stamps_s[f] > frame_stamps_s[f - 1])) {
      throw std::invalid_argument("estimateLensShiftTrajectory: frame stamps must increase (frame " +
                                  std::to_string(f) + ")");
    }
  }
  const int N = options.patch_count;
  const Eigen::Matrix3d& K = camera.K();
  const Eigen::Matrix3d K_inv = camera.Kinv();

  // Per pair, the gyro's rotation homographies; every track once, undistorted.
  std::vector<std::vector<Eigen::Matrix3d>> homographies(pairs.size());
  std::vector<Track> tracks;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const LensShiftPairObservation& pair = pairs[k];
    if (pair.frame_a < 0 || pair.frame_b <= pair.frame_a || pair.frame_b >= frame_count) {
      throw std::invalid_argument("estimateLensShiftTrajectory: pair " + std::to_string(k) +
                                  " has frames " + std::to_string(pair.frame_a) + " -> " +
                                  std::to_string(pair.frame_b) + " of " +
                                  std::to_string(frame_count));
    }
    if (static_cast<int>(pair.rotations.size()) != N) {
      throw std::invalid_argument("estimateLensShiftTrajectory: pair " + std::to_string(k) +
                                  " has " + std::to_string(pair.rotations.size()) +
                                  " rotations for " + std::to_string(N) + " patches");
    }
    for (const Eigen::Matrix3d& R : pair.rotations) homographies[k].push_back(K * R * K_inv);
    for (const FeatureMatch& m : pair.matches) {
      const Eigen::Vector2d a(m.point_a_px.x, m.point_a_px.y), b(m.point_b_px.x, m.point_b_px.y);
      tracks.push_back({static_cast<int>(k), patchIndexOfRow(a.y(), camera.height(), N),
                        camera.undistort(a), camera.undistort(b)});
    }
  }

  // Capture time of every lens position, in recording order (frame-major, then patch).
  const int positions = frame_count * N;
  std::vector<double> time_s(positions);
  for (int f = 0; f < frame_count; ++f) {
    for (int i = 0; i < N; ++i)
      time_s[f * N + i] = frame_stamps_s[f] + options.readout_time_s * (i + 0.5) / N;
  }

  const int unknowns = 2 * positions;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(unknowns);
  std::vector<double> residual_px(tracks.size(), 0.0);
  const double centre_weight = 1.0 / (options.centre_prior_px * options.centre_prior_px);
  const double walk = options.lens_random_walk_px_per_sqrt_s;
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    // Huber weights from the last pass's residuals; in the second half, outliers are out.
    const bool reject_outliers = iteration >= options.iterations / 2;
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(tracks.size() * 16 + static_cast<std::size_t>(unknowns) * 4);
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(unknowns);
    for (std::size_t t = 0; t < tracks.size(); ++t) {
      const Track& track = tracks[t];
      const LensShiftPairObservation& pair = pairs[track.pair];
      const int ia = unknownIndex(pair.frame_a, track.patch, N);
      const int ib = unknownIndex(pair.frame_b, track.patch, N);
      const Eigen::Vector2d s_a = x.segment<2>(ia), s_b = x.segment<2>(ib);
      Eigen::Matrix2d J_h;
      const Eigen::Vector2d predicted =
          applyHomography(homographies[track.pair][track.patch], track.a_px - s_a, &J_h) + s_b;
      const Eigen::Vector2d r = track.b_px - predicted;
      residual_px[t] = r.norm();
      double weight = 1.0;
      if (iteration > 0) {
        if (reject_outliers && residual_px[t] > options.outlier_px) continue;
        if (residual_px[t] > options.huber_px) weight = options.huber_px / residual_px[t];
      }
      // predicted(x + d) ~ predicted + A d with A = [-J_h (s_a), I (s_b)].
      const Eigen::Matrix2d A_a = -J_h;
      const int index[2] = {ia, ib};
      const Eigen::Matrix2d blocks[2] = {A_a, Eigen::Matrix2d::Identity()};
      for (int u = 0; u < 2; ++u) {
        gradient.segment<2>(index[u]) += weight * blocks[u].transpose() * r;
        for (int v = 0; v < 2; ++v) {
          const Eigen::Matrix2d block = weight * blocks[u].transpose() * blocks[v];
          for (int row = 0; row < 2; ++row)
            for (int col = 0; col < 2; ++col)
              entries.emplace_back(index[u] + row, index[v] + col, block(row, col));
        }
      }
    }
    // Priors: the centre on every position, the random walk between consecutive positions.
    for (int k = 0; k < unknowns; ++k) {
      entries.emplace_back(k, k, centre_weight);
      gradient[k] -= centre_weight * x[k];
    }
    for (int p = 0; p + 1 < positions; ++p) {
      const double dt = std::max(time_s[p + 1] - time_s[p], 1e-4);
      const double w = 1.0 / (walk * walk * dt);
      for (int axis = 0; axis < 2; ++axis) {
        const int k0 = 2 * p + axis, k1 = 2 * (p + 1) + axis;
        entries.emplace_back(k0, k0, w);
        entries.emplace_back(k1, k1, w);
        entries.emplace_back(k0, k1, -w);
        entries.emplace_back(k1, k0, -w);
        const double difference = x[k1] - x[k0];
        gradient[k0] += w * difference;
        gradient[k1] -= w * difference;
      }
    }
    Eigen::SparseMatrix<double> normal(unknowns, unknowns);
    normal.setFromTriplets(entries.begin(), entries.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
    if (solver.info() != Eigen::Success) {
      throw std::runtime_error("estimateLensShiftTrajectory: the normal equations are singular");
    }
    x += solver.solve(gradient);
  }

  LensShiftTrajectory out;
  out.patch_count = N;
  out.shift_px.assign(frame_count, std::vector<Eigen::Vector2d>(N, Eigen::Vector2d::Zero()));
  for (int f = 0; f < frame_count; ++f)
    for (int i = 0; i < N; ++i) out.shift_px[f][i] = x.segment<2>(unknownIndex(f, i, N));
  // Final residuals, per pair.
  std::vector<std::vector<double>> kept(pairs.size());
  for (std::size_t t = 0; t < tracks.size(); ++t) {
    const Track& track = tracks[t];
    const LensShiftPairObservation& pair = pairs[track.pair];
    const Eigen::Vector2d s_a = out.shift_px[pair.frame_a][track.patch];
    const Eigen::Vector2d s_b = out.shift_px[pair.frame_b][track.patch];
    const double r =
        (track.b_px -
         applyHomography(homographies[track.pair][track.patch], track.a_px - s_a, nullptr) - s_b)
            .norm();
    if (r <= options.outlier_px) kept[track.pair].push_back(r);
  }
  for (const auto& residuals : kept) {
    out.pair_inliers.push_back(static_cast<int>(residuals.size()));
    out.pair_median_residual_px.push_back(median(residuals));
  }
  return out;
}

}  // namespace deep_ois
