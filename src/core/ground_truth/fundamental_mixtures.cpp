#include "deep_ois/core/ground_truth/fundamental_mixtures.h"

#include "deep_ois/core/common/so3_and_statistics.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/calibration/rotation_alignment.h"

namespace deep_ois {

namespace {

using Vec9 = Eigen::Matrix<double, 9, 1>;

// Below this a mixture weight is 0 (see the weights in estimate()).
constexpr double kNegligibleWeight = 1e-200;

// One match, prepared once: undistorted pixels, Hartley-normalised points, unit bearings.
struct Track {
  Eigen::Vector3d a_px = Eigen::Vector3d::Zero();  // homogeneous undistorted pixels
  Eigen::Vector3d b_px = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_n = Eigen::Vector3d::Zero();  // homogeneous Hartley-normalised points
  Eigen::Vector3d b_n = Eigen::Vector3d::Zero();
  Eigen::Vector3d bear_a = Eigen::Vector3d::Zero();  // unit bearings in the camera frames
  Eigen::Vector3d bear_b = Eigen::Vector3d::Zero();
  int patch = 0;  // patch of the raw row in frame a
};

struct Problem {
  std::vector<Track> tracks;
  Eigen::MatrixXd weights;       // tracks x model patches, rows sum to 1
  std::vector<int> model_patch;  // per track, the model patch used for its residual
  int model_count = 1;
  Eigen::Matrix3d K, K_inv, T_a, T_b;
};

// Hartley: centroid to the origin, mean distance sqrt(2).
Eigen::Matrix3d hartleyTransform(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  double mean_distance = 0.0;
  for (const auto& p : points) mean_distance += (p - centroid).norm();
  mean_distance /= static_cast<double>(points.size());
  const double scale = mean_distance > 0.0 ? std::sqrt(2.0) / mean_distance : 1.0;
  Eigen::Matrix3d T;
  T << scale, 0.0, -scale * centroid.x(), 0.0, scale, -scale * centroid.y(), 0.0, 0.0, 1.0;
  return T;
}

// x_b^T F x_a as a row times vec(F) with vec row-major: entry 3r + c is xb_r * xa_c.
Eigen::Matrix<double, 1, 9> epipolarRow(const Eigen::Vector3d& xa, const Eigen::Vector3d& xb) {
  Eigen::Matrix<double, 1, 9> row;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) row(3 * r + c) = xb(r) * xa(c);
  }
  return row;
}

Eigen::Matrix3d unvec(const Vec9& f) {
  Eigen::Matrix3d F;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) F(r, c) = f(3 * r + c);
  }
  return F;
}

Vec9 vec(const Eigen::Matrix3d& F) {
  Vec9 f;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) f(3 * r + c) = F(r, c);
  }
  return f;
}

Eigen::Matrix3d enforceRank2(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s = svd.singularValues();
  s(2) = 0.0;
  return svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
}

// Sampson distance of a match to F (same coordinates as the points).
double sampsonDistance(const Eigen::Matrix3d& F, const Eigen::Vector3d& xa,
                       const Eigen::Vector3d& xb) {
  const Eigen::Vector3d Fx = F * xa;
  const Eigen::Vector3d Ftx = F.transpose() * xb;
  const double denominator = Fx.head<2>().squaredNorm() + Ftx.head<2>().squaredNorm();
  if (!(denominator > 0.0)) return std::numeric_limits<double>::infinity();
  return std::abs(xb.dot(Fx)) / std::sqrt(denominator);
}

double transferError(const Eigen::Matrix3d& H, const Track& track) {
  return ((H * track.a_px).hnormalized() - track.b_px.hnormalized()).norm();
}

// Linear 8-point in normalised coordinates over `indices`, rank 2, unit Frobenius norm.
Eigen::Matrix3d eightPoint(const Problem& problem, const std::vector<int>& indices) {
  Eigen::MatrixXd A(indices.size(), 9);
  for (size_t k = 0; k < indices.size(); ++k) {
    const Track& t = problem.tracks[indices[k]];
    A.row(k) = epipolarRow(t.a_n, t.b_n);
  }
  // The smallest singular vector of A^T A: A may have exactly 8 rows, where a thin SVD of A
  // lacks it.
  const Eigen::Matrix<double, 9, 9> normal = A.transpose() * A;
  Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> svd(normal, Eigen::ComputeFullV);
  const Eigen::Matrix3d F = enforceRank2(unvec(svd.matrixV().col(8)));
  return F / F.norm();
}

Eigen::Matrix3d denormalise(const Problem& problem, const Eigen::Matrix3d& F_n) {
  return problem.T_b.transpose() * F_n * problem.T_a;
}

std::vector<int> indicesOf(const std::vector<bool>& flags) {
  std::vector<int> indices;
  for (size_t j = 0; j < flags.size(); ++j) {
    if (flags[j]) indices.push_back(static_cast<int>(j));
  }
  return indices;
}

// `count` distinct entries of `pool`.
std::vector<int> drawSample(std::mt19937& rng, const std::vector<int>& pool, int count) {
  const int n = static_cast<int>(pool.size());
  std::vector<int> sample;
  while (static_cast<int>(sample.size()) < count) {
    const int index = pool[std::min(n - 1, static_cast<int>(uniform01(rng) * n))];
    if (std::find(sample.begin(), sample.end(), index) == sample.end()) sample.push_back(index);
  }
  return sample;
}

// MSAC over the tracks in `pool`: `fit` turns a sample into a model, `residual` scores a track
// (px). Returns the inlier flags (over all tracks, false outside the pool) of the best model.
template <typename Model, typename Fit, typename Residual>
std::vector<bool> msac(const Problem& problem, const std::vector<int>& pool, int sample_size,
                       const FundamentalMixturesOptions& o, std::uint32_t stream, Fit fit,
                       Residual residual) {
  const int n = static_cast<int>(problem.tracks.size());
  std::vector<bool> best(n, false);
  if (static_cast<int>(pool.size()) < sample_size) return best;
  std::mt19937 rng = streamGenerator(o.seed, stream);
  const double threshold_sq = o.ransac_threshold_px * o.ransac_threshold_px;
  double best_cost = std::numeric_limits<double>::infinity();
  int needed = o.ransac_max_iterations;
  for (int iteration = 0; iteration < needed; ++iteration) {
    const Model model = fit(drawSample(rng, pool, sample_size));
    double cost = 0.0;
    int inliers = 0;
    std::vector<bool> flags(n, false);
    for (int j : pool) {
      const double r = residual(model, j);
      const double r_sq = std::isfinite(r) ? r * r : threshold_sq;
      cost += std::min(r_sq, threshold_sq);
      if (r_sq < threshold_sq) {
        flags[j] = true;
        ++inliers;
      }
    }
    if (cost < best_cost) {
      best_cost = cost;
      best = flags;
      const double all_inlier = std::pow(static_cast<double>(inliers) / pool.size(), sample_size);
      if (all_inlier >= 1.0) break;
      if (all_inlier > 0.0) {
        const double estimate = std::log(1.0 - o.ransac_confidence) / std::log(1.0 - all_inlier);
        // Clamp in double: a tiny inlier ratio gives an estimate beyond int's range.
        needed = static_cast<int>(std::min<double>(o.ransac_max_iterations, std::ceil(estimate)));
      }
    }
  }
  return best;
}

// The robust stage: one global MSAC, then (when `local`) a local MSAC in every patch with enough
// tracks of its own, whose verdict replaces the global one there. A single global model misses
// the outer patches of a rolling-shutter frame by pixels when the rate changes during readout;
// the local models do not. Sparse patches keep the global verdict. Only the 2-point rotation is
// local: an 8-point F from a 45-row strip is too poorly conditioned to judge anything.
template <typename Model, typename Fit, typename Residual>
std::vector<bool> robustInliers(const Problem& problem, int sample_size, bool local,
                                const FundamentalMixturesOptions& o, std::uint32_t stream, Fit fit,
                                Residual residual) {
  const int n = static_cast<int>(problem.tracks.size());
  std::vector<int> all(n);
  for (int j = 0; j < n; ++j) all[j] = j;
  std::vector<bool> flags = msac<Model>(problem, all, sample_size, o, stream, fit, residual);
  if (problem.model_count == 1 || !local) return flags;
  for (int i = 0; i < problem.model_count; ++i) {
    std::vector<int> pool;
    for (int j = 0; j < n; ++j) {
      if (problem.model_patch[j] == i) pool.push_back(j);
    }
    // Twice the sample size: fewer tracks give a local consensus too weak to trust.
    if (static_cast<int>(pool.size()) < 2 * sample_size) continue;
    const std::vector<bool> local =
        msac<Model>(problem, pool, sample_size, o, stream + 100 * (i + 1), fit, residual);
    for (int j : pool) flags[j] = local[j];
  }
  return flags;
}

// Patches whose summed weight over `inliers` is below the minimum: they get the smoothness tie.
std::vector<bool> sparsePatches(const Problem& problem, const std::vector<int>& inliers,
                                const FundamentalMixturesOptions& o) {
  std::vector<bool> sparse(problem.model_count, false);
  for (int i = 0; i < problem.model_count; ++i) {
    double mass = 0.0;
    for (int j : inliers) mass += problem.weights(j, i);
    sparse[i] = mass < o.min_points_per_patch;
  }
  return sparse;
}

std::vector<int> neighbours(int i, int count) {
  std::vector<int> result;
  if (i > 0) result.push_back(i - 1);
  if (i + 1 < count) result.push_back(i + 1);
  return result;
}

// ---- Fundamental Mixtures ----------------------------------------------------------------

// With the default sigma = 0.001 h a track's weight is exactly 0 on all but its own patch (see
// kNegligibleWeight): skipping those terms saves most of the work and changes no bit of the sum.
Eigen::Matrix3d mixtureAt(const Problem& problem, const std::vector<Eigen::Matrix3d>& F, int j) {
  Eigen::Matrix3d mixed = Eigen::Matrix3d::Zero();
  for (int i = 0; i < problem.model_count; ++i) {
    const double w = problem.weights(j, i);
    if (w != 0.0) mixed += w * F[i];
  }
  return mixed;
}

// One linear solve of A f = 0 over `inliers`, rows scaled by `row_scale`. Sparse patches are tied
// to both neighbours (the paper ties to F_(i-1) only; both keeps a run of sparse patches at the
// top of the frame connected to the data below it).
bool solveMixture(const Problem& problem, const std::vector<int>& inliers,
                  const std::vector<double>& row_scale, const Eigen::Matrix3d& F_reference_n,
                  const FundamentalMixturesOptions& o, std::vector<Eigen::Matrix3d>* F_n) {
  const int N = problem.model_count;
  const std::vector<bool> sparse = sparsePatches(problem, inliers, o);
  int tie_count = 0;
  for (int i = 0; i < N; ++i) {
    if (sparse[i]) tie_count += static_cast<int>(neighbours(i, N).size());
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(inliers.size() + 9 * tie_count, 9 * N);
  int row = 0;
  for (int j : inliers) {
    const Eigen::Matrix<double, 1, 9> base =
        row_scale[j] * epipolarRow(problem.tracks[j].a_n, problem.tracks[j].b_n);
    for (int i = 0; i < N; ++i) A.block<1, 9>(row, 9 * i) = problem.weights(j, i) * base;
    ++row;
  }
  for (int i = 0; i < N; ++i) {
    if (!sparse[i]) continue;
    for (int k : neighbours(i, N)) {
      A.block<9, 9>(row, 9 * i).diagonal().setConstant(o.smoothness_lambda);
      A.block<9, 9>(row, 9 * k).diagonal().setConstant(-o.smoothness_lambda);
      row += 9;
    }
  }

  Eigen::VectorXd f(9 * N);
  if (o.scale_gauge == MixtureScaleGauge::kUnitNorm || N == 1) {
    // Square normal matrix: Jacobi SVD needs no QR preconditioner (Eigen's Householder code
    // trips GCC 12's -Wmaybe-uninitialized).
    const Eigen::MatrixXd normal = A.transpose() * A;
    Eigen::JacobiSVD<Eigen::MatrixXd, Eigen::NoQRPreconditioner> svd(normal, Eigen::ComputeFullV);
    f = svd.matrixV().col(9 * N - 1);
  } else {
    // f_i = g + Z y_i with g the unit reference and Z its orthogonal complement: <f_i, g> = 1.
    const Vec9 g = vec(F_reference_n).normalized();
    const Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> complement(g * g.transpose(),
                                                                   Eigen::ComputeFullU);
    const Eigen::Matrix<double, 9, 8> Z = complement.matrixU().rightCols<8>();
    Eigen::MatrixXd AZ(A.rows(), 8 * N);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(A.rows());
    for (int i = 0; i < N; ++i) {
      AZ.middleCols(8 * i, 8) = A.middleCols(9 * i, 9) * Z;
      rhs -= A.middleCols(9 * i, 9) * g;
    }
    // Normal equations: AZ is tall and the points are Hartley-normalised, so squaring its
    // condition number is affordable. Rank 8N is needed for a unique solution; the threshold
    // is (1e-7)^2, i.e. relative singular values of AZ below 1e-7 count as zero.
    const Eigen::MatrixXd normal = AZ.transpose() * AZ;
    Eigen::JacobiSVD<Eigen::MatrixXd, Eigen::NoQRPreconditioner> svd(
        normal, Eigen::ComputeFullU | Eigen::ComputeFullV);
    svd.setThreshold(1e-14);
    if (svd.rank() < 8 * N) return false;
    const Eigen::VectorXd y = svd.solve(AZ.transpose() * rhs);
    for (int i = 0; i < N; ++i) f.segment<9>(9 * i) = g + Z * y.segment<8>(8 * i);
  }
  if (!f.allFinite()) return false;
  F_n->assign(N, Eigen::Matrix3d::Zero());
  for (int i = 0; i < N; ++i) (*F_n)[i] = enforceRank2(unvec(f.segment<9>(9 * i)));
  return true;
}

// Rotation and translation direction of E = K^T F K chosen by cheirality over `votes`
// (tracks); false when no candidate puts a majority of them in front of both cameras.
bool decomposeFundamental(const Problem& problem, const Eigen::Matrix3d& F_px,
                          const std::vector<int>& votes, Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  const Eigen::Matrix3d E = problem.K.transpose() * F_px * problem.K;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if (U.determinant() < 0.0) U = -U;
  if (V.determinant() < 0.0) V = -V;
  Eigen::Matrix3d W;
  W << 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  const Eigen::Matrix3d rotations[2] = {U * W * V.transpose(), U * W.transpose() * V.transpose()};
  int best_count = -1;
  for (const Eigen::Matrix3d& candidate : rotations) {
    for (double sign : {1.0, -1.0}) {
      const Eigen::Vector3d translation = sign * U.col(2);
      int in_front = 0;
      for (int j : votes) {
        // z_a R f_a + t = z_b f_b, least squares in (z_a, z_b).
        Eigen::Matrix<double, 3, 2> M;
        M.col(0) = candidate * problem.tracks[j].bear_a;
        M.col(1) = -problem.tracks[j].bear_b;
        const Eigen::Vector2d z = (M.transpose() * M).ldlt().solve(-M.transpose() * translation);
        if (z(0) > 0.0 && z(1) > 0.0) ++in_front;
      }
      if (in_front > best_count) {
        best_count = in_front;
        *R = candidate;
        *t = translation;
      }
    }
  }
  return 2 * best_count > static_cast<int>(votes.size());
}

// Pixel F of camera motion (R, t): x_b^T K^-T [t]x R K^-1 x_a = 0.
Eigen::Matrix3d fundamentalOf(const Problem& problem, const Eigen::Matrix3d& R,
                              const Eigen::Vector3d& t) {
  return problem.K_inv.transpose() * skew(t) * R * problem.K_inv;
}

double signedSampson(const Eigen::Matrix3d& F, const Track& track) {
  const Eigen::Vector3d Fx = F * track.a_px;
  const Eigen::Vector3d Ftx = F.transpose() * track.b_px;
  const double denominator = Fx.head<2>().squaredNorm() + Ftx.head<2>().squaredNorm();
  return denominator > 0.0 ? track.b_px.dot(Fx) / std::sqrt(denominator) : 0.0;
}

// The per-patch motions as one model: rotation R_i per patch, one translation direction t
// (over one frame interval the camera's translation hardly changes between rows, while its
// rotation does). Refined by Levenberg-Marquardt on the Sampson distances of the inliers, px,
// plus the sparse patches' ties lambda * f * log(R_k^T R_i). A 45-row strip alone conditions
// its own F (8 dof of direction) poorly; sharing t leaves each patch only its 3 rotation dof.
struct MotionParameters {
  std::vector<Eigen::Matrix3d> R;
  Eigen::Vector3d t = Eigen::Vector3d::UnitX();
};

int tieRowCount(const std::vector<bool>& sparse, const FundamentalMixturesOptions& o) {
  const int N = static_cast<int>(sparse.size());
  int ties = 0;
  for (int i = 0; i < N; ++i) {
    if (sparse[i]) ties += static_cast<int>(neighbours(i, N).size());
  }
  return 3 * ties + (o.rotation_tie_lambda > 0.0 ? 3 * (N - 1) : 0);
}

// The tie rows (sparse patches to their neighbours, then the optional tie of all neighbours),
// px; they depend on the rotations only.
void tieResiduals(const Problem& problem, const std::vector<Eigen::Matrix3d>& R,
                  const std::vector<bool>& sparse, const FundamentalMixturesOptions& o,
                  Eigen::Ref<Eigen::VectorXd> r) {
  const int N = problem.model_count;
  const double focal_px = problem.K(0, 0);
  int row = 0;
  for (int i = 0; i < N; ++i) {
    if (!sparse[i]) continue;
    for (int k : neighbours(i, N)) {
      r.segment<3>(row) = o.smoothness_lambda * focal_px * logSO3(R[k].transpose() * R[i]);
      row += 3;
    }
  }
  if (o.rotation_tie_lambda > 0.0) {
    for (int i = 0; i + 1 < N; ++i) {
      r.segment<3>(row) = o.rotation_tie_lambda * focal_px * logSO3(R[i].transpose() * R[i + 1]);
      row += 3;
    }
  }
}

// Residuals (Sampson distances of the inliers, then the ties) and, when J is not null, their
// Jacobian w.r.t. the 3N + 2 parameters of perturb() at zero.
//
// Data rows, analytically. With e = x_b^T F x_a, g_a = (F x_a)_xy, g_b = (F^T x_b)_xy and
// d = |g_a|^2 + |g_b|^2, r = e / sqrt(d) changes under dF by
//   dr = <x_b x_a^T - (r / sqrt(d)) (g_a x_a^T + x_b g_b^T), dF> / sqrt(d)   (Frobenius),
// and the perturbations move F_i = K^-T [t]x R_i K^-1 by K^-T [t]x [e_k]x R_i K^-1 (rotation
// k of patch i, since R_i <- exp(x) R_i) and K^-T [b_k]x R_i K^-1 (translation along the
// tangent column b_k). This replaces a central-difference Jacobian that cost 4N + 4 residual
// evaluations per LM iteration; a check against central differences (hard and soft weights,
// both kinds of tie) agreed to 1e-9 relative.
//
// Tie rows by central differences: there are few of them, they need no translation columns,
// and log() has no cheap closed-form derivative.
void motionResiduals(const Problem& problem, const MotionParameters& m,
                     const std::vector<int>& inliers, const std::vector<bool>& sparse,
                     const FundamentalMixturesOptions& o,
                     const Eigen::Matrix<double, 3, 2>* tangent, Eigen::VectorXd* r,
                     Eigen::MatrixXd* J) {
  const int N = problem.model_count;
  const int data_rows = static_cast<int>(inliers.size());
  const int tie_rows = tieRowCount(sparse, o);
  r->resize(data_rows + tie_rows);
  std::vector<Eigen::Matrix3d> F(N);
  for (int i = 0; i < N; ++i) F[i] = fundamentalOf(problem, m.R[i], m.t);

  // Per patch, the derivative of F_i along each of its 3 rotation and the 2 translation
  // parameters.
  std::vector<Eigen::Matrix3d> dF_rotation, dF_translation;
  if (J != nullptr) {
    J->setZero(data_rows + tie_rows, 3 * N + 2);
    dF_rotation.resize(3 * N);
    dF_translation.resize(2 * N);
    const Eigen::Matrix3d left = problem.K_inv.transpose() * skew(m.t);
    for (int i = 0; i < N; ++i) {
      const Eigen::Matrix3d RK = m.R[i] * problem.K_inv;
      for (int k = 0; k < 3; ++k) {
        dF_rotation[3 * i + k] = left * skew(Eigen::Vector3d::Unit(k)) * RK;
      }
      for (int k = 0; k < 2; ++k) {
        dF_translation[2 * i + k] = problem.K_inv.transpose() * skew(tangent->col(k)) * RK;
      }
    }
  }

  for (int row = 0; row < data_rows; ++row) {
    const int j = inliers[row];
    const Track& track = problem.tracks[j];
    const Eigen::Matrix3d Fj = mixtureAt(problem, F, j);
    const Eigen::Vector3d Fx = Fj * track.a_px;
    const Eigen::Vector3d Ftx = Fj.transpose() * track.b_px;
    const double denominator = Fx.head<2>().squaredNorm() + Ftx.head<2>().squaredNorm();
    if (!(denominator > 0.0)) {
      (*r)(row) = 0.0;  // as signedSampson(); its Jacobian row stays zero
      continue;
    }
    const double norm = std::sqrt(denominator);
    const double residual = track.b_px.dot(Fx) / norm;
    (*r)(row) = residual;
    if (J == nullptr) continue;
    const Eigen::Vector3d g_a(Fx(0), Fx(1), 0.0), g_b(Ftx(0), Ftx(1), 0.0);
    const Eigen::Matrix3d M =
        (track.b_px * track.a_px.transpose() -
         (residual / norm) * (g_a * track.a_px.transpose() + track.b_px * g_b.transpose())) /
        norm;
    for (int i = 0; i < N; ++i) {
      const double w = problem.weights(j, i);
      if (w == 0.0) continue;
      for (int k = 0; k < 3; ++k) {
        (*J)(row, 3 * i + k) = w * M.cwiseProduct(dF_rotation[3 * i + k]).sum();
      }
      for (int k = 0; k < 2; ++k) {
        (*J)(row, 3 * N + k) += w * M.cwiseProduct(dF_translation[2 * i + k]).sum();
      }
    }
  }

  if (tie_rows == 0) return;
  tieResiduals(problem, m.R, sparse, o, r->tail(tie_rows));
  if (J == nullptr) return;
  constexpr double kStep = 1e-7;
  Eigen::VectorXd plus(tie_rows), minus(tie_rows);
  std::vector<Eigen::Matrix3d> R = m.R;
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d x = kStep * Eigen::Vector3d::Unit(k);
      R[i] = expSO3(x) * m.R[i];
      tieResiduals(problem, R, sparse, o, plus);
      R[i] = expSO3(-x) * m.R[i];
      tieResiduals(problem, R, sparse, o, minus);
      R[i] = m.R[i];
      J->block(data_rows, 3 * i + k, tie_rows, 1) = (plus - minus) / (2.0 * kStep);
    }
  }
}

// The refinement, by the package's solver (core/common/nonlinear_least_squares.h): each patch's
// rotation as exp(d_i) R_i (d_i a rotation vector from the start, 3 per patch) and the translation
// direction as the normalised t + T b (T a tangent basis at the start's t, 2 parameters). The
// analytic Jacobian of motionResiduals (along left perturbations and the tangent at the current
// point) is carried onto these coordinates by the left Jacobian of SO(3) and the normalisation.
void refineMotion(const Problem& problem, const std::vector<int>& inliers,
                  const FundamentalMixturesOptions& o, MotionParameters* m) {
  const int N = problem.model_count;
  const std::vector<bool> sparse = sparsePatches(problem, inliers, o);
  const MotionParameters origin = *m;
  auto tangentAt = [](const Eigen::Vector3d& t) {
    Eigen::JacobiSVD<Eigen::Matrix3d> basis(t * t.transpose(), Eigen::ComputeFullU);
    return Eigen::Matrix<double, 3, 2>(basis.matrixU().rightCols<2>());
  };
  const Eigen::Matrix<double, 3, 2> origin_tangent = tangentAt(origin.t);
  auto motionAt = [&](const Eigen::VectorXd& x) {
    MotionParameters out = origin;
    for (int i = 0; i < N; ++i) out.R[i] = expSO3(x.segment<3>(3 * i)) * origin.R[i];
    out.t = (origin.t + origin_tangent * x.tail<2>()).normalized();
    return out;
  };
  NonlinearLeastSquaresProblem refinement;
  for (int i = 0; i < N; ++i)
    for (int k = 0; k < 3; ++k)
      refinement.parameters.push_back({"patch " + std::to_string(i) + " rotation " + std::to_string(k)});
  refinement.parameters.push_back({"translation 0"});
  refinement.parameters.push_back({"translation 1"});
  refinement.residuals = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r) {
    motionResiduals(problem, motionAt(x), inliers, sparse, o, nullptr, r, nullptr);
    return true;
  };
  refinement.residuals_and_jacobian = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r, Eigen::MatrixXd* J) {
    const MotionParameters at = motionAt(x);
    const Eigen::Matrix<double, 3, 2> tangent = tangentAt(at.t);
    motionResiduals(problem, at, inliers, sparse, o, &tangent, r, J);
    for (int i = 0; i < N; ++i)
      J->middleCols<3>(3 * i) = J->middleCols<3>(3 * i) * leftJacobianSO3(x.segment<3>(3 * i));
    const Eigen::Vector3d u = origin.t + origin_tangent * x.tail<2>();
    J->rightCols<2>() = J->rightCols<2>() * (tangent.transpose() * origin_tangent / u.norm());
    return true;
  };
  NonlinearLeastSquaresOptions options;
  options.max_iterations = 20;
  options.function_tolerance = 1e-12;
  // Sampson distances are near their minimum after MSAC: the damping falls fast.
  options.damping = {1e-2, 10.0, 10.0, 1e-12, 10};
  const NonlinearLeastSquaresReport report =
      solveNonlinearLeastSquares(refinement, Eigen::VectorXd::Zero(3 * N + 2), options);
  if (report.usable() && report.final_cost <= report.initial_cost) *m = motionAt(report.values);
}

struct MixtureFit {
  bool ok = false;
  bool degenerate = false;            // enough inliers, but the cheirality test failed
  std::vector<Eigen::Matrix3d> F_px;  // refined, per model patch
  std::vector<Eigen::Matrix3d> R;     // per model patch
  std::vector<bool> inliers;
};

double patchCost(const Problem& problem, const Eigen::Matrix3d& F, const std::vector<int>& tracks,
                 double threshold_px) {
  double cost = 0.0;
  for (int j : tracks) {
    cost += std::min(std::pow(signedSampson(F, problem.tracks[j]), 2), threshold_px * threshold_px);
  }
  return cost;
}

// The paper's linear Fundamental Mixtures, then the shared-translation refinement started from
// its decomposed rotations (or the global F's rotation where that fits the patch better).
MixtureFit fitMixture(const Problem& problem, const FundamentalMixturesOptions& o) {
  MixtureFit fit;
  const int n = static_cast<int>(problem.tracks.size());
  const int N = problem.model_count;
  std::vector<bool> inliers = robustInliers<Eigen::Matrix3d>(
      problem, 8, false, o, 1,
      [&](const std::vector<int>& s) { return denormalise(problem, eightPoint(problem, s)); },
      [&](const Eigen::Matrix3d& F, int j) {
        return sampsonDistance(F, problem.tracks[j].a_px, problem.tracks[j].b_px);
      });
  const std::vector<int> used = indicesOf(inliers);
  if (static_cast<int>(used.size()) < o.min_inliers) return fit;

  // Global F: the gauge reference and the fallback start.
  const Eigen::Matrix3d reference_n = eightPoint(problem, used);
  MotionParameters motion;
  Eigen::Matrix3d R_global;
  if (!decomposeFundamental(problem, denormalise(problem, reference_n), used, &R_global,
                            &motion.t)) {
    fit.degenerate = true;
    return fit;
  }
  motion.R.assign(N, R_global);

  // Linear mixture: a plain pass, then one with rows divided by their Sampson gradient.
  std::vector<double> row_scale(n, 1.0);
  std::vector<Eigen::Matrix3d> F_n;
  bool linear_ok = false;
  for (int pass = 0; pass < 2; ++pass) {
    if (!solveMixture(problem, used, row_scale, reference_n, o, &F_n)) break;
    linear_ok = true;
    std::vector<double> scales;
    for (int j : used) {
      const Eigen::Matrix3d F = mixtureAt(problem, F_n, j);
      const Track& t = problem.tracks[j];
      const double gradient = std::sqrt((F * t.a_n).head<2>().squaredNorm() +
                                        (F.transpose() * t.b_n).head<2>().squaredNorm());
      row_scale[j] = gradient > 0.0 ? 1.0 / gradient : 1.0;
      scales.push_back(row_scale[j]);
    }
    // Typical row scale 1, so lambda keeps its meaning; clamped so that no row dominates.
    const double typical = median(scales);
    for (double& scale : row_scale) scale = std::clamp(scale / typical, 0.1, 10.0);
  }
  if (linear_ok) {
    for (int i = 0; i < N; ++i) {
      std::vector<int> own;
      for (int j : used) {
        if (problem.model_patch[j] == i) own.push_back(j);
      }
      const std::vector<int>& votes =
          static_cast<double>(own.size()) < o.min_points_per_patch ? used : own;
      Eigen::Matrix3d R;
      Eigen::Vector3d t;
      if (!decomposeFundamental(problem, denormalise(problem, F_n[i]), votes, &R, &t)) continue;
      const double threshold = o.ransac_threshold_px;
      if (patchCost(problem, fundamentalOf(problem, R, motion.t), own, threshold) <
          patchCost(problem, fundamentalOf(problem, R_global, motion.t), own, threshold)) {
        motion.R[i] = R;
      }
    }
  }

  for (int iteration = 0; iteration < o.refinement_iterations; ++iteration) {
    const std::vector<int> current = indicesOf(inliers);
    if (static_cast<int>(current.size()) < o.min_inliers) return fit;
    refineMotion(problem, current, o, &motion);
    std::vector<Eigen::Matrix3d> F(N);
    for (int i = 0; i < N; ++i) F[i] = fundamentalOf(problem, motion.R[i], motion.t);
    std::vector<bool> next(n, false);
    for (int j = 0; j < n; ++j) {
      next[j] = std::abs(signedSampson(mixtureAt(problem, F, j), problem.tracks[j])) <
                o.inlier_threshold_px;
    }
    const bool converged = next == inliers;
    inliers = next;
    if (converged) break;
  }
  fit.inliers = inliers;
  fit.R = motion.R;
  for (int i = 0; i < N; ++i) fit.F_px.push_back(fundamentalOf(problem, motion.R[i], motion.t));
  fit.ok = static_cast<int>(indicesOf(inliers).size()) >= o.min_inliers;
  return fit;
}

// ---- Rotation-only fallback --------------------------------------------------------------

struct RotationFit {
  bool ok = false;
  std::vector<Eigen::Matrix3d> R;  // per model patch
  std::vector<bool> inliers;
};

// Per-patch weighted Procrustes; sparse patches add lambda * (neighbour rotations) to their
// cross-covariance, the minimiser of the same tie as the F solve, by Gauss-Seidel sweeps.
std::vector<Eigen::Matrix3d> fitPatchRotations(const Problem& problem,
                                               const std::vector<int>& inliers,
                                               const FundamentalMixturesOptions& o) {
  const int N = problem.model_count;
  std::vector<Eigen::Matrix3d> M(N, Eigen::Matrix3d::Zero());
  Eigen::Matrix3d M_all = Eigen::Matrix3d::Zero();
  for (int j : inliers) {
    const Eigen::Matrix3d outer = problem.tracks[j].bear_b * problem.tracks[j].bear_a.transpose();
    M_all += outer;
    for (int i = 0; i < N; ++i) M[i] += problem.weights(j, i) * outer;
  }
  const std::vector<bool> sparse = sparsePatches(problem, inliers, o);
  std::vector<Eigen::Matrix3d> R(N, kabsch(M_all));
  for (int i = 0; i < N; ++i) {
    if (!sparse[i]) R[i] = kabsch(M[i]);
  }
  for (int sweep = 0; sweep < 20; ++sweep) {
    for (int i = 0; i < N; ++i) {
      if (!sparse[i]) continue;
      Eigen::Matrix3d tied = M[i];
      for (int k : neighbours(i, N)) tied += o.smoothness_lambda * R[k];
      R[i] = kabsch(tied);
    }
  }
  return R;
}

RotationFit fitRotations(const Problem& problem, const FundamentalMixturesOptions& o) {
  RotationFit fit;
  const int n = static_cast<int>(problem.tracks.size());
  std::vector<bool> inliers = robustInliers<Eigen::Matrix3d>(
      problem, 2, true, o, 2,
      [&](const std::vector<int>& s) {
        Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
        for (int j : s) M += problem.tracks[j].bear_b * problem.tracks[j].bear_a.transpose();
        return Eigen::Matrix3d(problem.K * kabsch(M) * problem.K_inv);
      },
      [&](const Eigen::Matrix3d& H, int j) { return transferError(H, problem.tracks[j]); });
  for (int iteration = 0; iteration < o.refinement_iterations; ++iteration) {
    const std::vector<int> used = indicesOf(inliers);
    if (static_cast<int>(used.size()) < o.min_inliers) return fit;
    fit.R = fitPatchRotations(problem, used, o);
    std::vector<bool> next(n, false);
    for (int j = 0; j < n; ++j) {
      const Eigen::Matrix3d H = problem.K * fit.R[problem.model_patch[j]] * problem.K_inv;
      next[j] = transferError(H, problem.tracks[j]) < o.inlier_threshold_px;
    }
    const bool converged = next == inliers;
    inliers = next;
    if (converged) break;
  }
  fit.inliers = inliers;
  fit.ok = static_cast<int>(indicesOf(inliers).size()) >= o.min_inliers;
  return fit;
}

FundamentalMixturesResult reject(FundamentalMixturesStatus status, const std::string& reason) {
  FundamentalMixturesResult result;
  result.status = status;
  result.reason = reason;
  return result;
}

int populatedPatches(const Problem& problem, const std::vector<bool>& flags) {
  std::set<int> patches;
  for (size_t j = 0; j < flags.size(); ++j) {
    if (flags[j]) patches.insert(problem.tracks[j].patch);
  }
  return static_cast<int>(patches.size());
}

FundamentalMixturesResult estimate(const std::vector<FeatureMatch>& matches,
                                   const CameraModel& camera, const FundamentalMixturesOptions& o,
                                   bool global) {
  const std::string options_error = o.validate();
  if (!options_error.empty()) {
    throw std::invalid_argument("FundamentalMixturesOptions: " + options_error);
  }
  const std::string camera_error = camera.validate();
  if (!camera_error.empty()) throw std::invalid_argument("CameraModel: " + camera_error);

  const int n = static_cast<int>(matches.size());
  if (n < o.min_inliers) {
    std::ostringstream why;
    why << "too few matches: " << n << " < min_inliers " << o.min_inliers;
    return reject(FundamentalMixturesStatus::kTooFewMatches, why.str());
  }

  Problem problem;
  problem.K = camera.K();
  problem.K_inv = camera.Kinv();
  problem.model_count = global ? 1 : o.patch_count;
  const int N = o.patch_count;
  const double h = camera.height();
  std::vector<Eigen::Vector2d> points_a, points_b;
  for (const FeatureMatch& m : matches) {
    Eigen::Vector2d a(m.point_a_px.x, m.point_a_px.y), b(m.point_b_px.x, m.point_b_px.y);
    Track t;
    t.patch = patchIndexOfRow(a.y(), camera.height(), N);
    if (camera.hasDistortion()) {
      a = camera.undistort(a);
      b = camera.undistort(b);
    }
    t.a_px = a.homogeneous();
    t.b_px = b.homogeneous();
    t.bear_a = (problem.K_inv * t.a_px).normalized();
    t.bear_b = (problem.K_inv * t.b_px).normalized();
    points_a.push_back(a);
    points_b.push_back(b);
    problem.tracks.push_back(t);
  }
  if (populatedPatches(problem, std::vector<bool>(n, true)) < o.min_populated_patches) {
    std::ostringstream why;
    why << "all matches lie in fewer than min_populated_patches (" << o.min_populated_patches
        << ") row patches: the other patches would be extrapolated, not measured";
    return reject(FundamentalMixturesStatus::kPointsInOnePatch, why.str());
  }
  problem.T_a = hartleyTransform(points_a);
  problem.T_b = hartleyTransform(points_b);
  for (Track& t : problem.tracks) {
    t.a_n = problem.T_a * t.a_px;
    t.b_n = problem.T_b * t.b_px;
  }

  // Gaussian weights on the raw row in frame a, centred on patch middles; in the log domain
  // because sigma = 0.001 h underflows exp() a few pixels from a centre.
  problem.weights = Eigen::MatrixXd::Ones(n, problem.model_count);
  problem.model_patch.assign(n, 0);
  if (!global) {
    const double sigma_px = o.weight_sigma_fraction * h;
    for (int j = 0; j < n; ++j) {
      const double row = matches[j].point_a_px.y;
      Eigen::VectorXd log_w(N);
      for (int i = 0; i < N; ++i) {
        const double centre = (i + 0.5) * h / N - 0.5;
        log_w(i) = -0.5 * std::pow((row - centre) / sigma_px, 2);
      }
      Eigen::VectorXd w = (log_w.array() - log_w.maxCoeff()).exp();
      w /= w.sum();
      // Eigen's vectorised exp() clamps its argument near -708, so a far patch gets a weight of
      // ~1e-308 (or a subnormal) rather than 0, and products with it are subnormal numbers, which
      // the CPU handles ~100x slower than normal ones: with the default sigma this made every
      // solve here tens of times slower. Weights this small cannot change any sum at double
      // precision: make them exactly 0.
      w = (w.array() < kNegligibleWeight).select(0.0, w);
      problem.weights.row(j) = w.transpose();
      problem.model_patch[j] = problem.tracks[j].patch;
    }
  }

  const MixtureFit mixture = fitMixture(problem, o);
  const RotationFit rotation = fitRotations(problem, o);

  FundamentalMixturesResult result;
  std::vector<Eigen::Matrix3d> R_model;
  // Model selection (see ModelSelection): tracks with visible parallax are the F inliers that the
  // rotation-only fit rejects.
  bool use_fundamental = mixture.ok && !rotation.ok;
  if (mixture.ok && rotation.ok) {
    int f_inliers = 0, parallax = 0;
    for (int j = 0; j < n; ++j) {
      if (!mixture.inliers[j]) continue;
      ++f_inliers;
      if (!rotation.inliers[j]) ++parallax;
    }
    result.parallax_share = static_cast<double>(parallax) / f_inliers;
    use_fundamental = o.model_selection == ModelSelection::kFundamental ||
                      result.parallax_share > o.max_parallax_share;
  }

  std::vector<bool> inliers;
  if (use_fundamental) {
    result.model = global ? MotionModel::kGlobalFundamental : MotionModel::kFundamentalMixtures;
    R_model = mixture.R;
    inliers = mixture.inliers;
    for (int i = 0; i < N; ++i) result.fundamentals.push_back(mixture.F_px[global ? 0 : i]);
  } else if (rotation.ok) {
    result.model =
        global ? MotionModel::kGlobalRotationOnlyFallback : MotionModel::kRotationOnlyFallback;
    R_model = rotation.R;
    inliers = rotation.inliers;
    result.fundamentals.assign(N, Eigen::Matrix3d::Zero());
  } else if (mixture.degenerate) {
    return reject(FundamentalMixturesStatus::kDegenerate,
                  "degenerate: the global fundamental matrix has no decomposition with most points "
                  "in front of both cameras, and no rotation model has enough inliers");
  } else {
    std::ostringstream why;
    why << "too few inliers: neither a fundamental matrix nor a rotation model kept "
        << o.min_inliers << " of the " << n << " matches";
    return reject(FundamentalMixturesStatus::kTooFewInliers, why.str());
  }

  if (populatedPatches(problem, inliers) < o.min_populated_patches) {
    std::ostringstream why;
    why << "the inliers lie in fewer than min_populated_patches (" << o.min_populated_patches
        << ") row patches: the other patches would be extrapolated, not measured";
    return reject(FundamentalMixturesStatus::kPointsInOnePatch, why.str());
  }

  result.inliers = inliers;
  result.inlier_counts.assign(N, 0);
  for (int i = 0; i < N; ++i) {
    result.rotations.push_back(R_model[global ? 0 : i]);
    result.homographies.push_back(rotationHomography(problem.K, result.rotations.back()));
  }
  std::vector<double> residuals;
  for (int j = 0; j < n; ++j) {
    if (!inliers[j]) continue;
    ++result.inlier_count;
    ++result.inlier_counts[problem.tracks[j].patch];
    residuals.push_back(
        transferError(result.homographies[problem.tracks[j].patch], problem.tracks[j]));
  }
  result.median_rotation_residual_px = median(residuals);
  for (const auto& H : result.homographies) {
    if (!H.allFinite()) {
      return reject(FundamentalMixturesStatus::kSolverFailure,
                    "solver failure: a homography has non-finite entries");
    }
  }
  return result;
}

}  // namespace

std::string FundamentalMixturesOptions::validate() const {
  std::ostringstream why;
  if (patch_count < 1) {
    why << "patch_count must be at least 1 (got " << patch_count << ")";
  } else if (!(weight_sigma_fraction > 0.0) || !std::isfinite(weight_sigma_fraction)) {
    why << "weight_sigma_fraction must be positive and finite (got " << weight_sigma_fraction
        << ")";
  } else if (!(min_points_per_patch >= 0.0) || !std::isfinite(min_points_per_patch)) {
    why << "min_points_per_patch must be non-negative (got " << min_points_per_patch << ")";
  } else if (!(smoothness_lambda > 0.0) || !std::isfinite(smoothness_lambda)) {
    why << "smoothness_lambda must be positive and finite (got " << smoothness_lambda << ")";
  } else if (!(rotation_tie_lambda >= 0.0) || !std::isfinite(rotation_tie_lambda)) {
    why << "rotation_tie_lambda must be non-negative and finite (got " << rotation_tie_lambda
        << ")";
  } else if (min_inliers < 8) {
    why << "min_inliers must be at least 8, the linear solver's minimum (got " << min_inliers
        << ")";
  } else if (min_populated_patches < 1 || min_populated_patches > patch_count) {
    why << "min_populated_patches must be in [1, patch_count] (got " << min_populated_patches
        << ")";
  } else if (!(ransac_threshold_px > 0.0) || !std::isfinite(ransac_threshold_px)) {
    why << "ransac_threshold_px must be positive and finite (got " << ransac_threshold_px << ")";
  } else if (!(inlier_threshold_px > 0.0) || !std::isfinite(inlier_threshold_px)) {
    why << "inlier_threshold_px must be positive and finite (got " << inlier_threshold_px << ")";
  } else if (ransac_max_iterations < 1) {
    why << "ransac_max_iterations must be at least 1 (got " << ransac_max_iterations << ")";
  } else if (!(ransac_confidence > 0.0 && ransac_confidence < 1.0)) {
    why << "ransac_confidence must be in (0, 1) (got " << ransac_confidence << ")";
  } else if (refinement_iterations < 1) {
    why << "refinement_iterations must be at least 1 (got " << refinement_iterations << ")";
  } else if (!(max_parallax_share >= 0.0 && max_parallax_share <= 1.0)) {
    why << "max_parallax_share must be in [0, 1] (got " << max_parallax_share << ")";
  }
  return why.str();
}

const char* toString(MotionModel model) {
  switch (model) {
    case MotionModel::kNone:
      return "none";
    case MotionModel::kFundamentalMixtures:
      return "fundamental_mixtures";
    case MotionModel::kGlobalFundamental:
      return "global_fundamental";
    case MotionModel::kRotationOnlyFallback:
      return "rotation_only_fallback";
    case MotionModel::kGlobalRotationOnlyFallback:
      return "global_rotation_only_fallback";
  }
  return "unknown";
}

const char* toString(FundamentalMixturesStatus status) {
  switch (status) {
    case FundamentalMixturesStatus::kOk:
      return "ok";
    case FundamentalMixturesStatus::kTooFewMatches:
      return "too_few_matches";
    case FundamentalMixturesStatus::kTooFewInliers:
      return "too_few_inliers";
    case FundamentalMixturesStatus::kPointsInOnePatch:
      return "points_in_one_patch";
    case FundamentalMixturesStatus::kDegenerate:
      return "degenerate";
    case FundamentalMixturesStatus::kSolverFailure:
      return "solver_failure";
  }
  return "unknown";
}

FundamentalMixturesResult estimateFundamentalMixtures(const std::vector<FeatureMatch>& matches,
                                                      const CameraModel& camera,
                                                      const FundamentalMixturesOptions& options) {
  return estimate(matches, camera, options, false);
}

FundamentalMixturesResult estimateGlobalFundamental(const std::vector<FeatureMatch>& matches,
                                                    const CameraModel& camera,
                                                    const FundamentalMixturesOptions& options) {
  return estimate(matches, camera, options, true);
}

}  // namespace deep_ois
