#include "deep_ois/core/calibration/camera_imu_calibration.h"

#include "deep_ois/core/common/so3_and_statistics.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <iomanip>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/calibration/camera_imu_coarse_alignment.h"
#include "deep_ois/core/gyro/gyro_orientation_table.h"
#include "deep_ois/core/calibration/rotation_alignment.h"

namespace deep_ois {

const char* toString(LensShiftHandling handling) {
  switch (handling) {
    case LensShiftHandling::kNone: return "none";
    case LensShiftHandling::kPerFrameShift: return "per_frame_shift";
  }
  return "unknown";
}

std::string CalibrationOptions::validate() const {
  std::ostringstream why;
  if (!std::isfinite(time_offset_s) || std::abs(time_offset_s) > 10.0) {
    why << "time_offset_s must be within +-10 s (got " << time_offset_s << ")";
  } else if (!estimate_readout_time && !(readout_time_s >= 0.0 && readout_time_s <= 1.0)) {
    why << "readout_time_s must be in [0, 1] s when the readout is held (got " << readout_time_s << ")";
  } else if (!std::isfinite(readout_time_s) || readout_time_s > 1.0) {
    why << "readout_time_s must be at most 1 s, or negative for the default (got " << readout_time_s << ")";
  } else if (!gyro_bias_rad_s.allFinite()) {
    why << "gyro_bias_rad_s must be finite";
  } else if (!isProperRotation(imu_to_camera_rotation)) {
    why << "imu_to_camera_rotation must be a proper rotation matrix (orthonormal, det +1)";
  } else if (!(max_imu_gap_s > 0.0)) {
    why << "max_imu_gap_s must be positive (got " << max_imu_gap_s << ")";
  } else if (estimate_time_offset && !(max_abs_time_offset_s > 0.0 && max_abs_time_offset_s <= 5.0)) {
    why << "max_abs_time_offset_s must be in (0, 5] s (got " << max_abs_time_offset_s << ")";
  } else if (estimate_time_offset &&
             !(coarse_time_step_s > 0.0 && coarse_time_step_s <= max_abs_time_offset_s)) {
    why << "coarse_time_step_s must be in (0, max_abs_time_offset_s] (got " << coarse_time_step_s << ")";
  } else if (!std::isfinite(max_readout_time_s) || max_readout_time_s > 1.0) {
    why << "max_readout_time_s must be at most 1 s, or negative for the frame interval (got "
        << max_readout_time_s << ")";
  } else if (lens_shift_row_order < 0 || lens_shift_row_order > 3) {
    why << "lens_shift_row_order must be 0..3 (got " << lens_shift_row_order << ")";
  } else if (max_iterations < 1) {
    why << "max_iterations must be at least 1 (got " << max_iterations << ")";
  } else if (!(robust_scale_factor > 0.0) || !(min_robust_scale_px > 0.0)) {
    why << "robust_scale_factor and min_robust_scale_px must be positive";
  } else if (min_pairs < 1 || min_tracks_per_pair < 3) {
    why << "min_pairs must be >= 1 and min_tracks_per_pair >= 3";
  } else if (!(min_excitation_rate_rad_s >= 0.0)) {
    why << "min_excitation_rate_rad_s must be >= 0";
  } else if (!(systematic_time_offset_s >= 0.0) || !(systematic_readout_time_s >= 0.0) ||
             !(systematic_rotation_rad >= 0.0) || !(systematic_gyro_bias_rad_s >= 0.0) ||
             !std::isfinite(systematic_time_offset_s + systematic_readout_time_s + systematic_rotation_rad +
                            systematic_gyro_bias_rad_s)) {
    why << "the systematic_* uncertainties must be finite and >= 0";
  } else if (!(readout_boundary_s >= 0.0) || !std::isfinite(readout_boundary_s)) {
    why << "readout_boundary_s must be >= 0 seconds (0 = never)";
  } else if (!(statistical_sigma_factor >= 1.0 && statistical_sigma_factor <= 100.0)) {
    why << "statistical_sigma_factor must be in [1, 100] (got " << statistical_sigma_factor << ")";
  } else if (!(max_time_offset_sigma_s > 0.0) || !(max_readout_time_sigma_s > 0.0) ||
             !(max_rotation_sigma_rad > 0.0) || !(max_gyro_bias_sigma_rad_s > 0.0)) {
    why << "the max_*_sigma limits must be positive";
  }
  return why.str();
}

KltOptions calibrationKltOptions() {
  KltOptions options;
  options.window_size_px = 11;
  return options;
}

std::string CalibrationResult::reason() const {
  std::string joined;
  for (const std::string& refusal : refusals) joined += (joined.empty() ? "" : "; ") + refusal;
  return joined;
}

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

// Parameter layout of the refinement: time offset, readout, bias (3, IMU frame), rotation
// increment (3, camera frame: R_cam_imu <- exp(e) R_cam_imu).
constexpr int kParameterCount = 8;
constexpr int kOffset = 0;
constexpr int kReadout = 1;
constexpr int kBias = 2;
constexpr int kRotation = 5;
using ParameterVector = Eigen::Matrix<double, kParameterCount, 1>;
using ParameterMatrix = Eigen::Matrix<double, kParameterCount, kParameterCount>;

// Pairs per cluster of the cluster-robust covariance: 5 pairs (1/6 s at 30 fps), about the time
// over which hand-held translation and the lens stay correlated.
constexpr std::size_t kPairsPerCluster = 5;

// OIS lens shift of each frame: a translation of the image (a principal-point shift) that is a
// polynomial of the row, since the lens moves during the readout. Coefficients per power (x, y);
// storage for the cubic, powers above the configured order stay zero (only the prior sees them).
constexpr int kMaxShiftOrder = 3;
constexpr int kShiftCount = 2 * (kMaxShiftOrder + 1);
using ShiftBasis = Eigen::Matrix<double, 2, kShiftCount>;
using ShiftBlock = Eigen::Matrix<double, kShiftCount, kShiftCount>;
using ShiftByParameter = Eigen::Matrix<double, kShiftCount, kParameterCount>;
using ShiftVector = Eigen::Matrix<double, kShiftCount, 1>;
// Prior on every shift coefficient (px^-2, against unit track weights): (0.1 px track noise / 3 px
// lens stroke)^2, i.e. the lens stays within a few pixels of its centre. Without it a lens that
// drifts steadily is, to first order, a gyro bias about the pan/tilt axes, and a lens decentred
// on average is a tilt of the mount; the stroke limit is what tells them apart.
constexpr double kShiftPriorWeight = 1e-3;

ShiftBasis shiftBasis(double row_fraction, int order) {
  ShiftBasis A = ShiftBasis::Zero();
  const double row = row_fraction - 0.5;
  double power = 1.0;
  for (int k = 0; k <= order; ++k) {
    A(0, 2 * k) = power;
    A(1, 2 * k + 1) = power;
    power *= row;
  }
  return A;
}

struct State {
  double time_offset_s = 0.0;
  double readout_time_s = 0.0;
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_cam_imu = Eigen::Matrix3d::Identity();
  std::vector<ShiftVector> shifts;  // per shift block (frame), when the lens shift is modelled
};

// One track, ready for the model.
struct TrackPoint {
  Eigen::Vector2d x_a;          // undistorted pixel in frame a
  Eigen::Vector2d x_b;          // undistorted pixel in frame b
  double row_fraction_a = 0.0;  // raw row / height: capture delay = readout * fraction
  double row_fraction_b = 0.0;
};

struct PreparedPair {
  int source_index = 0;  // into CalibrationData::pairs
  int frame_a = 0, frame_b = 0;
  double stamp_a_s = 0.0;
  double stamp_b_s = 0.0;
  std::vector<TrackPoint> points;
  std::vector<Eigen::Vector3d> bearings_a, bearings_b;  // unit rays, for the coarse fit
};

std::string describeSeconds(double seconds) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << seconds * 1e3 << " ms";
  return out.str();
}

// Undistorted pixels and rays of every track, in pairs; pairs with too few tracks are left out
// (the caller counts what remains).
std::vector<PreparedPair> preparePairs(const CalibrationData& data, int min_tracks) {
  const CameraModel& camera = data.camera;
  const double height = camera.height();
  std::vector<PreparedPair> prepared;
  for (std::size_t i = 0; i < data.pairs.size(); ++i) {
    const CalibrationPair& pair = data.pairs[i];
    const int frames = static_cast<int>(data.frame_stamps_s.size());
    if (pair.frame_a < 0 || pair.frame_b >= frames || pair.frame_b <= pair.frame_a) {
      std::ostringstream why;
      why << "calibration: pair " << i << " names frames " << pair.frame_a << " -> " << pair.frame_b
          << ", but frames 0.." << frames - 1 << " exist and a must come before b";
      throw std::invalid_argument(why.str());
    }
    if (static_cast<int>(pair.matches.size()) < min_tracks) continue;
    PreparedPair out;
    out.source_index = static_cast<int>(i);
    out.frame_a = pair.frame_a;
    out.frame_b = pair.frame_b;
    out.stamp_a_s = data.frame_stamps_s[pair.frame_a];
    out.stamp_b_s = data.frame_stamps_s[pair.frame_b];
    for (const FeatureMatch& match : pair.matches) {
      const Eigen::Vector2d raw_a(match.point_a_px.x, match.point_a_px.y);
      const Eigen::Vector2d raw_b(match.point_b_px.x, match.point_b_px.y);
      if (!raw_a.allFinite() || !raw_b.allFinite()) continue;
      TrackPoint point;
      point.x_a = camera.hasDistortion() ? camera.undistort(raw_a) : raw_a;
      point.x_b = camera.hasDistortion() ? camera.undistort(raw_b) : raw_b;
      point.row_fraction_a = raw_a.y() / height;
      point.row_fraction_b = raw_b.y() / height;
      out.points.push_back(point);
      out.bearings_a.push_back((camera.Kinv() * point.x_a.homogeneous()).normalized());
      out.bearings_b.push_back((camera.Kinv() * point.x_b.homogeneous()).normalized());
    }
    if (static_cast<int>(out.points.size()) >= min_tracks) prepared.push_back(std::move(out));
  }
  return prepared;
}

// One evaluation at a state: the cost and, when asked, the normal equations of the calibration
// parameters with the lens shifts eliminated (Schur complement), plus what recovers the shift
// step from a parameter step: shift_step = -(shift_rhs + shift_gain * parameter_step).
struct Evaluation {
  double cost = 0.0;  // sum of w |e|^2 (px^2) plus the shift prior, at the state
  std::vector<double> residual_norms_px;  // per track, pairs in order
  double weight_sum = 0.0;
  ParameterMatrix H = ParameterMatrix::Zero();
  ParameterVector g = ParameterVector::Zero();
  Eigen::VectorXd shift_rhs;
  Eigen::MatrixXd shift_gain;
};

// What one track contributes at a state, before the parallax is removed.
struct PointTerms {
  double weight = 1.0;
  Eigen::Vector2d error = Eigen::Vector2d::Zero();                 // predicted - observed, px
  Eigen::Matrix<double, 2, 3> D = Eigen::Matrix<double, 2, 3>::Zero();  // d(pixel)/d(camera point)
  Eigen::Matrix<double, 2, kParameterCount> J = Eigen::Matrix<double, 2, kParameterCount>::Zero();
  ShiftBasis G_a = ShiftBasis::Zero();  // d(error)/d(shift of frame a), d(error)/d(shift of frame b)
  ShiftBasis G_b = ShiftBasis::Zero();
  Eigen::Matrix2d projector = Eigen::Matrix2d::Identity();  // removes the parallax direction
};

// A camera translation t between the frames moves track i by (inverse depth_i) D_i t on top of the
// rotation: a known direction per track (for a given t), an unknown amount. The translation
// direction u of the pair is fitted to the residuals (the one whose per-track directions
// D_i u explain most of them, by alternating per-track amounts and u), then each track keeps only
// the residual component across its own parallax direction: depth, and so parallax, no longer
// matters, at the price of one of the two components of every track. Exact for any depth; without
// translation it removes the component the noise happens to favour (information, not accuracy, is
// lost).
void removeParallax(std::vector<PointTerms>& terms) {
  auto explained = [&](const Eigen::Vector3d& u) {
    double sum = 0.0;
    for (const PointTerms& term : terms) {
      const Eigen::Vector2d v = term.D * u;
      const double norm2 = v.squaredNorm();
      if (norm2 > 0.0) sum += term.weight * std::pow(v.dot(term.error), 2) / norm2;
    }
    return sum;
  };
  // Start from the best of a few directions (forward, sideways, diagonals), then alternate.
  const double r = std::sqrt(0.5);
  const Eigen::Vector3d starts[] = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {r, r, 0}, {r, -r, 0},
                                    {r, 0, r}, {-r, 0, r}, {0, r, r}, {0, -r, r}};
  Eigen::Vector3d u = starts[0];
  double best = explained(u);
  for (const Eigen::Vector3d& start : starts) {
    const double value = explained(start);
    if (value > best) {
      best = value;
      u = start;
    }
  }
  for (int iteration = 0; iteration < 4; ++iteration) {
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (const PointTerms& term : terms) {
      const Eigen::Vector2d v = term.D * u;
      const double norm2 = v.squaredNorm();
      if (!(norm2 > 0.0)) continue;
      const double amount = v.dot(term.error) / norm2;
      M.noalias() += term.weight * amount * amount * term.D.transpose() * term.D;
      b.noalias() += term.weight * amount * term.D.transpose() * term.error;
    }
    const Eigen::Vector3d next = M.ldlt().solve(b);
    if (!next.allFinite() || next.norm() == 0.0) break;
    const double value = explained(next.normalized());
    if (!(value > best)) break;
    best = value;
    u = next.normalized();
  }
  for (PointTerms& term : terms) {
    const Eigen::Vector2d v = term.D * u;
    const double norm = v.norm();
    term.projector = Eigen::Matrix2d::Identity();
    if (norm > 0.0) term.projector -= (v / norm) * (v / norm).transpose();
  }
}

// The reprojection model over all prepared pairs:
//   x_b = pi(K R_b_a K^-1 (x_a - s_a(row_a))) + s_b(row_b)
// with s the lens shift of each frame (zero for a fixed lens). The gyro table is rebuilt when the
// bias changes.
class ReprojectionProblem {
 public:
  ReprojectionProblem(const std::vector<PreparedPair>& pairs, const ImuSampleBuffer& gyro,
                      const Eigen::Matrix3d& K, RateInterpolation interpolation, double max_gap_s,
                      LensShiftHandling lens_shift, int shift_order, bool eliminate_parallax)
      : pairs_(pairs), gyro_(gyro), K_(K), K_inv_(K.inverse()), shift_order_(shift_order),
        model_shift_(lens_shift == LensShiftHandling::kPerFrameShift), eliminate_parallax_(eliminate_parallax) {
    integration_.interpolation = interpolation;
    integration_.max_sample_gap_s = max_gap_s;
    for (const PreparedPair& pair : pairs_) {
      track_count_ += pair.points.size();
      if (!model_shift_) continue;
      for (int frame : {pair.frame_a, pair.frame_b}) {
        if (!shift_block_.count(frame)) {
          const int block = static_cast<int>(shift_block_.size());
          shift_block_[frame] = block;
        }
      }
    }
  }

  std::size_t trackCount() const { return track_count_; }
  int shiftBlockCount() const { return static_cast<int>(shift_block_.size()); }
  // Shift coefficients that are estimated (the prior alone holds the others).
  int shiftUnknownCount() const { return shiftBlockCount() * 2 * (shift_order_ + 1); }

  // With `pair_scores` (needs `jacobian` and, when shifts are modelled, the `shift_gain` of an
  // evaluation at the same state): each pair's score sum_i w_i J_i^T r_i with the shifts' response
  // to the parameters folded into J, for the cluster-robust covariance.
  Evaluation evaluate(const State& state, const std::vector<double>& weights, bool jacobian,
                      const Eigen::MatrixXd* shift_gain = nullptr,
                      std::vector<ParameterVector>* pair_scores = nullptr) {
    const GyroOrientationTable& table = tableFor(state.bias);
    const int blocks = shiftBlockCount();
    Evaluation out;
    out.residual_norms_px.reserve(track_count_);
    std::vector<ShiftBlock> diagonal;
    std::map<std::pair<int, int>, ShiftBlock> off_diagonal;
    std::vector<ShiftByParameter> coupling;
    std::vector<ShiftVector> gradient;
    if (jacobian && blocks > 0) {
      diagonal.assign(blocks, ShiftBlock::Zero());
      coupling.assign(blocks, ShiftByParameter::Zero());
      gradient.assign(blocks, ShiftVector::Zero());
    }
    const Eigen::Matrix3d& R = state.R_cam_imu;
    std::size_t index = 0;
    std::vector<PointTerms> terms;
    for (const PreparedPair& pair : pairs_) {
      const int block_a = blocks > 0 ? shift_block_.at(pair.frame_a) : -1;
      const int block_b = blocks > 0 ? shift_block_.at(pair.frame_b) : -1;
      terms.resize(pair.points.size());
      for (std::size_t k = 0; k < pair.points.size(); ++k) {
        const TrackPoint& point = pair.points[k];
        PointTerms& term = terms[k];
        term.weight = weights.empty() ? 1.0 : weights[index + k];
        ShiftBasis A_a = ShiftBasis::Zero(), A_b = ShiftBasis::Zero();
        Eigen::Vector2d x_a = point.x_a, shift_b = Eigen::Vector2d::Zero();
        if (blocks > 0) {
          A_a = shiftBasis(point.row_fraction_a, shift_order_);
          A_b = shiftBasis(point.row_fraction_b, shift_order_);
          x_a -= A_a * state.shifts[block_a];
          shift_b = A_b * state.shifts[block_b];
        }
        const Eigen::Vector3d ray_a = K_inv_ * x_a.homogeneous();
        const double t_a = pair.stamp_a_s + state.time_offset_s + state.readout_time_s * point.row_fraction_a;
        const double t_b = pair.stamp_b_s + state.time_offset_s + state.readout_time_s * point.row_fraction_b;
        const Eigen::Matrix3d delta = table.relativeRotation(t_a, t_b);
        const Eigen::Matrix3d R_b_a = R * delta.transpose() * R.transpose();
        const Eigen::Vector3d Y = R_b_a * ray_a;
        const Eigen::Vector3d q = K_ * Y;
        const Eigen::Vector2d projected = q.head<2>() / q.z();
        term.error = projected + shift_b - point.x_b;
        // d(projected)/dY of the pinhole projection: also the direction in which a translation
        // of the camera moves the point (parallax), scaled by its inverse depth.
        term.D.row(0) = (K_.row(0) - projected.x() * K_.row(2)) / q.z();
        term.D.row(1) = (K_.row(1) - projected.y() * K_.row(2)) / q.z();
        if (!jacobian) continue;

        // Camera-frame rates at both capture times: moving t_b by dt turns the camera by c_b dt
        // more (Y -> Y - c_b x Y dt); moving t_a turns the start (ray -> ray + c_a x ray dt).
        const Eigen::Matrix<double, 2, 3>& D = term.D;
        const Eigen::Vector3d c_a = R * table.rate(t_a);
        const Eigen::Vector3d c_b = R * table.rate(t_b);
        const Eigen::Vector3d dY_dta = R_b_a * c_a.cross(ray_a);
        const Eigen::Vector3d dY_dtb = -c_b.cross(Y);
        Eigen::Matrix<double, 2, kParameterCount>& J = term.J;
        J.col(kOffset) = D * (dY_dta + dY_dtb);
        J.col(kReadout) = D * (point.row_fraction_a * dY_dta + point.row_fraction_b * dY_dtb);
        // A bias increment e removes e (t_b - t_a) of rotation: R_b_a -> exp(R e dt) R_b_a (first
        // order in the small inter-frame rotation).
        J.block<2, 3>(0, kBias) = D * (-(t_b - t_a) * skew(Y) * R);
        // R_cam_imu -> exp(e) R_cam_imu: R_b_a -> exp(e) R_b_a exp(-e).
        J.block<2, 3>(0, kRotation) = D * (-skew(Y) + R_b_a * skew(ray_a));
        if (blocks > 0) {
          // The shift of frame a moves the point before the rotation, that of frame b after it.
          const Eigen::Matrix2d homography_jacobian = D * R_b_a * K_inv_.leftCols<2>();
          term.G_a = -homography_jacobian * A_a;
          term.G_b = A_b;
        }
      }
      index += pair.points.size();

      // Parallax: remove from every residual the component along its own parallax direction.
      if (eliminate_parallax_) removeParallax(terms);

      ShiftBlock between = ShiftBlock::Zero();
      ParameterVector score = ParameterVector::Zero();
      for (const PointTerms& term : terms) {
        const double w = term.weight;
        const Eigen::Matrix2d& P = term.projector;
        const Eigen::Vector2d error = P * term.error;
        out.residual_norms_px.push_back(error.norm());
        out.cost += w * error.squaredNorm();
        out.weight_sum += w;
        if (!jacobian) continue;
        const Eigen::Matrix<double, 2, kParameterCount> J = P * term.J;
        out.H.noalias() += w * J.transpose() * J;
        out.g.noalias() += w * J.transpose() * error;
        if (pair_scores) {
          Eigen::Matrix<double, 2, kParameterCount> J_total = J;
          if (blocks > 0 && shift_gain) {
            // The shifts re-fit when the parameters move: d(shift)/d(parameters) = -shift_gain.
            J_total.noalias() -= P * term.G_a * shift_gain->middleRows<kShiftCount>(block_a * kShiftCount);
            J_total.noalias() -= P * term.G_b * shift_gain->middleRows<kShiftCount>(block_b * kShiftCount);
          }
          score.noalias() += w * J_total.transpose() * error;
        }
        if (blocks > 0) {
          const ShiftBasis G_a = P * term.G_a;
          const ShiftBasis G_b = P * term.G_b;
          diagonal[block_a].noalias() += w * G_a.transpose() * G_a;
          diagonal[block_b].noalias() += w * G_b.transpose() * G_b;
          between.noalias() += w * G_a.transpose() * G_b;
          coupling[block_a].noalias() += w * G_a.transpose() * J;
          coupling[block_b].noalias() += w * G_b.transpose() * J;
          gradient[block_a].noalias() += w * G_a.transpose() * error;
          gradient[block_b].noalias() += w * G_b.transpose() * error;
        }
      }
      if (pair_scores) pair_scores->push_back(score);
      if (jacobian && blocks > 0) {
        auto inserted = off_diagonal.emplace(std::make_pair(block_a, block_b), ShiftBlock::Zero());
        inserted.first->second += between;
      }
    }
    for (int b = 0; b < blocks; ++b) out.cost += kShiftPriorWeight * state.shifts[b].squaredNorm();
    if (jacobian && blocks > 0) eliminateShifts(state, diagonal, off_diagonal, coupling, gradient, out);
    return out;
  }

 private:
  // Schur complement of the (block-banded, sparse) shift unknowns.
  void eliminateShifts(const State& state, const std::vector<ShiftBlock>& diagonal,
                       const std::map<std::pair<int, int>, ShiftBlock>& off_diagonal,
                       const std::vector<ShiftByParameter>& coupling, const std::vector<ShiftVector>& gradient,
                       Evaluation& out) const {
    const int blocks = shiftBlockCount();
    const int size = blocks * kShiftCount;
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<std::size_t>(blocks) * kShiftCount * kShiftCount * 3);
    auto addBlock = [&](int row_block, int col_block, const ShiftBlock& block) {
      for (int i = 0; i < kShiftCount; ++i) {
        for (int j = 0; j < kShiftCount; ++j) {
          if (block(i, j) != 0.0) triplets.emplace_back(row_block * kShiftCount + i, col_block * kShiftCount + j, block(i, j));
        }
      }
    };
    for (int b = 0; b < blocks; ++b) {
      addBlock(b, b, diagonal[b] + kShiftPriorWeight * ShiftBlock::Identity());
    }
    for (const auto& [key, block] : off_diagonal) {
      addBlock(key.first, key.second, block);
      addBlock(key.second, key.first, block.transpose());
    }
    Eigen::SparseMatrix<double> N(size, size);
    N.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::MatrixXd B(size, kParameterCount);
    Eigen::VectorXd c(size);
    for (int b = 0; b < blocks; ++b) {
      B.middleRows<kShiftCount>(b * kShiftCount) = coupling[b];
      c.segment<kShiftCount>(b * kShiftCount) = gradient[b] + kShiftPriorWeight * state.shifts[b];
    }
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(N);
    out.shift_rhs = solver.solve(c);
    out.shift_gain = solver.solve(B);
    out.H.noalias() -= B.transpose() * out.shift_gain;
    out.g.noalias() -= B.transpose() * out.shift_rhs;
  }

  const GyroOrientationTable& tableFor(const Eigen::Vector3d& bias) {
    if (!table_ || bias != table_bias_) {
      integration_.gyro_bias_rad_s = bias;
      table_ = std::make_unique<GyroOrientationTable>(gyro_, integration_);
      table_bias_ = bias;
    }
    return *table_;
  }

  const std::vector<PreparedPair>& pairs_;
  const ImuSampleBuffer& gyro_;
  Eigen::Matrix3d K_;
  Eigen::Matrix3d K_inv_;
  int shift_order_;
  bool model_shift_;
  bool eliminate_parallax_;
  std::map<int, int> shift_block_;  // frame index -> shift block
  IntegrationOptions integration_;
  std::size_t track_count_ = 0;
  std::unique_ptr<GyroOrientationTable> table_;
  Eigen::Vector3d table_bias_ = Eigen::Vector3d::Zero();
};

bool removesParallax(const CalibrationOptions& options) {
  return options.eliminate_parallax && options.lens_shift == LensShiftHandling::kNone;
}

// Cauchy weights from the residuals: scale = factor x robust sigma (MAD of the 2-D residual
// norm: median |e| = 1.1774 sigma for isotropic Gaussian noise in 2-D, 0.6745 sigma once the
// parallax direction is removed and one component is left).
std::vector<double> cauchyWeights(const std::vector<double>& residual_norms_px,
                                  const CalibrationOptions& options, double* scale_px) {
  const double sigma = median(residual_norms_px) / (removesParallax(options) ? 0.6745 : 1.1774);
  const double scale = std::max(options.robust_scale_factor * sigma, options.min_robust_scale_px);
  if (scale_px) *scale_px = scale;
  std::vector<double> weights(residual_norms_px.size());
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const double r = residual_norms_px[i] / scale;
    weights[i] = 1.0 / (1.0 + r * r);
  }
  return weights;
}

// The lens shifts' part of a Gauss-Newton step, given the parameters' part (Schur back-substitution).
void applyShiftStep(State& state, const Evaluation& evaluation, const ParameterVector& parameter_step) {
  if (state.shifts.empty()) return;
  const Eigen::VectorXd shift_step = -(evaluation.shift_rhs + evaluation.shift_gain * parameter_step);
  for (std::size_t b = 0; b < state.shifts.size(); ++b) {
    state.shifts[b] += shift_step.segment<kShiftCount>(static_cast<Eigen::Index>(b) * kShiftCount);
  }
}

State applyStep(const State& state, const ParameterVector& step, double max_readout_s) {
  State next = state;
  next.time_offset_s += step(kOffset);
  next.readout_time_s = std::clamp(state.readout_time_s + step(kReadout), 0.0, max_readout_s);
  next.bias += step.segment<3>(kBias);
  next.R_cam_imu = expSO3(step.segment<3>(kRotation)) * state.R_cam_imu;
  return next;
}

// Principal RMS rates of the gyro over [begin, end] (IMU clock), descending, bias removed.
Eigen::Vector3d principalRateRms(const std::vector<ImuSample>& gyro, double begin_s, double end_s,
                                 const Eigen::Vector3d& bias) {
  Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
  int count = 0;
  for (const ImuSample& sample : gyro) {
    if (sample.stamp_s < begin_s || sample.stamp_s > end_s) continue;
    const Eigen::Vector3d w = sample.angular_velocity_rad_s - bias;
    moment += w * w.transpose();
    ++count;
  }
  if (count == 0) return Eigen::Vector3d::Zero();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(moment / count);
  const Eigen::Vector3d values = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // ascending
  return Eigen::Vector3d(values(2), values(1), values(0));
}

double medianFrameInterval(const std::vector<double>& stamps) {
  std::vector<double> intervals;
  for (std::size_t i = 1; i < stamps.size(); ++i) intervals.push_back(stamps[i] - stamps[i - 1]);
  return median(intervals);
}

void checkInput(const CalibrationData& data, const CalibrationOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("calibration options: " + problem);
  const std::string camera_problem = data.camera.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("calibration: camera: " + camera_problem);
  if (data.frame_stamps_s.size() < 2) {
    throw std::invalid_argument("calibration: needs at least two frame stamps");
  }
  for (std::size_t i = 1; i < data.frame_stamps_s.size(); ++i) {
    if (!(data.frame_stamps_s[i] > data.frame_stamps_s[i - 1])) {
      std::ostringstream why;
      why << std::setprecision(9) << "calibration: frame stamps must increase strictly, but frame " << i << " ("
          << data.frame_stamps_s[i] << " s) does not come after frame " << i - 1 << " ("
          << data.frame_stamps_s[i - 1] << " s)";
      throw std::invalid_argument(why.str());
    }
  }
  if (data.gyro.size() < 2) throw std::invalid_argument("calibration: needs gyro samples, got " + std::to_string(data.gyro.size()));
}

ImuSampleBuffer bufferOf(const std::vector<ImuSample>& gyro) {
  const double span = gyro.back().stamp_s - gyro.front().stamp_s;
  ImuSampleBuffer buffer(span + 1.0);
  for (const ImuSample& sample : gyro) {
    const ImuAddResult added = buffer.add(sample);
    if (!added.accepted()) throw std::invalid_argument("calibration: gyro: " + added.reason);
  }
  return buffer;
}

}  // namespace

namespace {
CalibrationResult calibrateOnce(const CalibrationData& data, const CalibrationOptions& options);
}  // namespace

CalibrationResult calibrateCameraImu(const CalibrationData& data, const CalibrationOptions& options) {
  CalibrationResult result = calibrateOnce(data, options);
  CameraImuCalibration& c = result.calibration;
  if (!result.converged && result.iterations >= options.max_iterations) {
    result.notes.push_back("the refinement stopped at its iteration cap (" + std::to_string(options.max_iterations) +
                           " iterations) without converging");
  }
  // A mount that wandered off the axis permutation the search found must earn it: a refinement
  // that does not lower the residual below that of the permutation held has not found a mount, it
  // has drifted along a weakly determined direction (and its 1-sigma, from the curvature there,
  // would be confidently wrong).
  if (options.estimate_rotation && result.iterations > 0) {
    result.nearest_permutation_index = nearestSignedAxisPermutation(c.imu_to_camera_rotation);
    const Eigen::Matrix3d& permutation =
        signedAxisPermutations()[static_cast<std::size_t>(result.nearest_permutation_index)];
    result.mount_from_permutation_deg = rotationAngleBetween(permutation, c.imu_to_camera_rotation) * kRadToDeg;
    const double sigma_deg = c.rotation_sigma_rad.maxCoeff() * kRadToDeg;
    if (result.mount_from_permutation_deg > std::max(2.0, 3.0 * sigma_deg)) {
      CalibrationOptions held = options;
      held.estimate_rotation = false;
      held.imu_to_camera_rotation = permutation;
      const CalibrationResult at_permutation = calibrateOnce(data, held);
      result.seconds += at_permutation.seconds;
      std::ostringstream why;
      why << std::fixed << std::setprecision(3) << "mount: the refinement ended "
          << std::setprecision(1) << result.mount_from_permutation_deg << " deg from the nearest axis permutation"
          << (result.converged ? "" : " without converging (iteration cap " + std::to_string(options.max_iterations) + ")")
          << ", with a 1-sigma of " << std::setprecision(2) << sigma_deg << " deg, but holding that permutation fits ";
      // Unconverged, the refined mount is where the iteration cap stopped a drift, whatever its
      // residual: a mount off the axes must be a converged minimum that fits better.
      const bool fits_as_well = at_permutation.median_residual_px <= 1.01 * result.median_residual_px;
      if (fits_as_well || !result.converged) {
        why << (fits_as_well ? "as well" : "only " + std::to_string(static_cast<int>(std::lround(
                                                100.0 * (at_permutation.median_residual_px / result.median_residual_px - 1.0)))) +
                                                " % worse")
            << " (median residual " << std::setprecision(3) << at_permutation.median_residual_px << " px against "
            << result.median_residual_px << " px)" << (fits_as_well ? "" : " and the refinement did not converge")
            << ": the data do not determine the mount beyond the permutation, so the refined mount and its "
               "1-sigma are not to be trusted. If the IMU is mounted along the camera's axes (a phone), hold it: "
               "--rotation ";
        for (int i = 0; i < 9; ++i) why << (i ? "," : "") << static_cast<int>(std::lround(permutation(i / 3, i % 3)));
        result.refusals.push_back(why.str());
        result.status = CalibrationStatus::kRefused;
      } else {
        why << "worse (median residual " << std::setprecision(3) << at_permutation.median_residual_px << " px against "
            << result.median_residual_px << " px): the mount is off the camera's axes";
        result.notes.push_back(why.str());
      }
    }
  }
  if (!options.estimate_readout_time || !(options.readout_boundary_s > 0.0) ||
      !(c.readout_time_s < options.readout_boundary_s)) {
    return result;
  }
  // At the readout's lower bound: the other answer, a global shutter, widens the intervals.
  CalibrationOptions held = options;
  held.estimate_readout_time = false;
  held.readout_time_s = 0.0;
  const CalibrationResult global = calibrateOnce(data, held);
  const double offset_shift_s = c.time_offset_s - global.calibration.time_offset_s;
  c.time_offset_sigma_s = std::hypot(c.time_offset_sigma_s, offset_shift_s);
  c.readout_time_sigma_s = std::max(c.readout_time_sigma_s, c.readout_time_s);
  std::ostringstream note;
  note << std::fixed << std::setprecision(3) << "readout " << c.readout_time_s * 1e3
       << " ms is at its lower bound: with the readout held at 0 (a global shutter) the offset is "
       << global.calibration.time_offset_s * 1e3 << " ms; the reported intervals hold both (offset +- "
       << c.time_offset_sigma_s * 1e3 << " ms, readout +- " << c.readout_time_sigma_s * 1e3
       << " ms). For a global-shutter camera pass --readout 0";
  result.notes.push_back(note.str());
  result.seconds += global.seconds;
  return result;
}

namespace {
CalibrationResult calibrateOnce(const CalibrationData& data, const CalibrationOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  checkInput(data, options);
  CalibrationResult result;
  auto finish = [&]() -> CalibrationResult {
    result.status = result.refusals.empty() ? CalibrationStatus::kOk : CalibrationStatus::kRefused;
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return result;
  };

  const ImuSampleBuffer gyro = bufferOf(data.gyro);
  const double frame_interval_s = medianFrameInterval(data.frame_stamps_s);
  const double max_readout_s = options.max_readout_time_s >= 0.0 ? options.max_readout_time_s : frame_interval_s;
  const double initial_readout_s = options.readout_time_s >= 0.0 ? std::min(options.readout_time_s, max_readout_s)
                                                                  : 0.5 * max_readout_s;
  const double focal_px = 0.5 * (data.camera.K()(0, 0) + data.camera.K()(1, 1));

  std::vector<PreparedPair> pairs = preparePairs(data, options.min_tracks_per_pair);
  if (static_cast<int>(pairs.size()) < options.min_pairs) {
    std::ostringstream why;
    why << "calibration: only " << pairs.size() << " of " << data.pairs.size() << " frame pairs have at least "
        << options.min_tracks_per_pair << " tracks; at least " << options.min_pairs
        << " such pairs are needed (more frames, more texture)";
    throw std::invalid_argument(why.str());
  }

  // ---- Coarse, global stage: offset grid x 24 signed axis permutations. -------------------
  IntegrationOptions zero_bias;
  zero_bias.interpolation = options.interpolation;
  zero_bias.max_sample_gap_s = options.max_imu_gap_s;
  const GyroOrientationTable coarse_table(gyro, zero_bias);
  // An OIS lens shift disturbs the pairs' rotation fits by pixels; a wider loss keeps them.
  const double coarse_scale_px = options.lens_shift == LensShiftHandling::kNone ? 1.0 : 3.0;
  std::vector<CoarsePair> coarse_pairs;
  for (const PreparedPair& pair : pairs) {
    CoarsePair coarse;
    coarse.stamp_a_s = pair.stamp_a_s;
    coarse.stamp_b_s = pair.stamp_b_s;
    double rows = 0.0;
    for (const TrackPoint& point : pair.points) rows += point.row_fraction_a;
    coarse.mean_row_fraction = rows / pair.points.size();
    coarse.image_rotation_rad = fitImageRotation(pair.bearings_a, pair.bearings_b, coarse_scale_px / focal_px);
    coarse_pairs.push_back(coarse);
  }
  CoarseAlignmentOptions coarse_options;
  coarse_options.max_abs_time_offset_s = options.estimate_time_offset ? options.max_abs_time_offset_s : 0.0;
  coarse_options.time_step_s = options.coarse_time_step_s;
  coarse_options.held_time_offset_s = options.time_offset_s;
  coarse_options.readout_time_s = initial_readout_s;
  coarse_options.search_rotation = options.estimate_rotation;
  coarse_options.held_rotation = options.imu_to_camera_rotation;
  coarse_options.scale_rad = coarse_scale_px / focal_px;
  const CoarseAlignment coarse = coarseCameraImuAlignment(coarse_table, coarse_pairs, coarse_options);
  result.coarse_time_offset_s = coarse.time_offset_s;
  result.coarse_permutation_index = coarse.permutation_index;

  State state;
  state.time_offset_s = options.estimate_time_offset ? coarse.time_offset_s : options.time_offset_s;
  state.readout_time_s = initial_readout_s;
  state.bias = options.estimate_gyro_bias ? coarse.gyro_bias_rad_s : options.gyro_bias_rad_s;
  state.R_cam_imu = options.estimate_rotation ? coarse.imu_to_camera_rotation : options.imu_to_camera_rotation;

  // ---- Motion prerequisites. ----------------------------------------------------------------
  // Too little motion for any quantity: refused, with the coarse stage's values as the (untrusted)
  // calibration so that the caller still sees what was found.
  auto refuseUnobservable = [&](const std::string& why) -> CalibrationResult {
    result.refusals.push_back(why);
    result.calibration.time_offset_s = state.time_offset_s;
    result.calibration.readout_time_s = state.readout_time_s;
    result.calibration.gyro_bias_rad_s = state.bias;
    result.calibration.imu_to_camera_rotation = state.R_cam_imu;
    return finish();
  };
  const double first_s = data.frame_stamps_s.front() + state.time_offset_s;
  const double last_s = data.frame_stamps_s.back() + state.time_offset_s + max_readout_s;
  result.rate_rms_rad_s = principalRateRms(data.gyro, first_s, last_s, state.bias);
  std::ostringstream rates;
  rates << std::fixed << std::setprecision(3) << result.rate_rms_rad_s(0) << ", " << result.rate_rms_rad_s(1)
        << ", " << result.rate_rms_rad_s(2) << " rad/s";
  if (result.rate_rms_rad_s(0) < options.min_excitation_rate_rad_s) {
    std::ostringstream why;
    why << "motion: the camera hardly rotates (gyro RMS about its principal axes " << rates.str()
        << "; at least " << options.min_excitation_rate_rad_s
        << " rad/s is needed about one axis, two for the rotation): no quantity is observable; record "
           "again while turning the camera by hand about all three axes";
    return refuseUnobservable(why.str());
  }
  // The rate check passes a still camera on a vibrating mount; what the tracks see between frames
  // is what carries the information.
  std::vector<double> image_rotation_px;
  for (const CoarsePair& pair : coarse_pairs) image_rotation_px.push_back(pair.image_rotation_rad.norm() * focal_px);
  result.median_image_rotation_px = median(image_rotation_px);
  if (result.median_image_rotation_px < options.min_median_image_rotation_px) {
    std::ostringstream why;
    why << std::fixed << std::setprecision(2)
        << "motion: the camera hardly rotates between frames (median " << result.median_image_rotation_px
        << " px of image rotation per frame pair, " << std::setprecision(3)
        << result.median_image_rotation_px / focal_px * kRadToDeg << " deg; at least " << std::setprecision(2)
        << options.min_median_image_rotation_px << " px, " << std::setprecision(3)
        << options.min_median_image_rotation_px / focal_px * kRadToDeg
        << " deg at this focal length, is needed): track noise and translation parallax are as large as the "
           "rotation, so no quantity is observable; record again while turning the camera by hand about "
           "all three axes";
    return refuseUnobservable(why.str());
  }
  if (options.estimate_rotation && result.rate_rms_rad_s(1) < options.min_excitation_rate_rad_s) {
    std::ostringstream why;
    why << "IMU-camera rotation: the gyro shows rotation about one axis only (RMS about its principal axes "
        << rates.str() << "; at least " << options.min_excitation_rate_rad_s
        << " rad/s is needed about two axes): the rotation about that axis is unobservable; turn the "
           "camera about a second axis too, or hold the rotation at a known value";
    result.refusals.push_back(why.str());
  }

  // ---- Continuous refinement. ---------------------------------------------------------------
  // Pairs the gyro covers around the coarse offset (the refinement moves it by milliseconds).
  std::vector<PreparedPair> refined_pairs;
  for (PreparedPair& pair : pairs) {
    const double margin_s = 0.05;
    if (coarse_table.coverage(pair.stamp_a_s + state.time_offset_s - margin_s,
                              pair.stamp_b_s + state.time_offset_s + max_readout_s + margin_s).ok()) {
      refined_pairs.push_back(std::move(pair));
    }
  }
  if (static_cast<int>(refined_pairs.size()) < options.min_pairs) {
    std::ostringstream why;
    why << "calibration: the gyro covers only " << refined_pairs.size() << " of the " << pairs.size()
        << " usable frame pairs at the time offset found (" << describeSeconds(state.time_offset_s) << "); at least "
        << options.min_pairs << " are needed";
    throw std::invalid_argument(why.str());
  }
  ReprojectionProblem problem(refined_pairs, gyro, data.camera.K(), options.interpolation, options.max_imu_gap_s,
                              options.lens_shift, options.lens_shift_row_order, removesParallax(options));
  result.pairs_used = static_cast<int>(refined_pairs.size());
  result.tracks_used = static_cast<int>(problem.trackCount());
  state.shifts.assign(problem.shiftBlockCount(), ShiftVector::Zero());

  std::vector<bool> active(kParameterCount, false);
  active[kOffset] = options.estimate_time_offset;
  active[kReadout] = options.estimate_readout_time;
  for (int i = 0; i < 3; ++i) {
    active[kBias + i] = options.estimate_gyro_bias;
    active[kRotation + i] = options.estimate_rotation;
  }
  const int n = static_cast<int>(std::count(active.begin(), active.end(), true));
  // Held parameters get a unit diagonal and no gradient: their step is exactly zero, and fixed-size
  // 8x8 algebra serves every combination.
  auto restrictToActive = [&](const Evaluation& evaluation, ParameterMatrix& H, ParameterVector& g) {
    H = evaluation.H;
    g = evaluation.g;
    for (int i = 0; i < kParameterCount; ++i) {
      if (active[i]) continue;
      H.row(i).setZero();
      H.col(i).setZero();
      H(i, i) = 1.0;
      g(i) = 0.0;
    }
  };

  Evaluation current = problem.evaluate(state, {}, problem.shiftBlockCount() > 0);
  if (problem.shiftBlockCount() > 0) {
    // Start the lens shifts at their best fit to the coarse calibration.
    applyShiftStep(state, current, ParameterVector::Zero());
    current = problem.evaluate(state, {}, false);
  }
  result.initial_median_residual_px = median(current.residual_norms_px);
  std::vector<double> weights = cauchyWeights(current.residual_norms_px, options, nullptr);
  double lambda = 1e-3;
  int quiet_iterations = 0;
  for (int iteration = 0; iteration < options.max_iterations && n > 0; ++iteration) {
    result.iterations = iteration + 1;
    current = problem.evaluate(state, weights, true);
    ParameterMatrix H;
    ParameterVector g;
    restrictToActive(current, H, g);
    bool accepted = false;
    ParameterVector step = ParameterVector::Zero();
    Evaluation trial;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      ParameterMatrix damped = H;
      for (int i = 0; i < kParameterCount; ++i) damped(i, i) += lambda * std::max(H(i, i), 1e-12);
      step = damped.ldlt().solve(-g);
      State candidate = applyStep(state, step, max_readout_s);
      applyShiftStep(candidate, current, step);
      trial = problem.evaluate(candidate, weights, false);
      if (trial.cost < current.cost) {
        state = candidate;
        accepted = true;
        lambda = std::max(lambda * 0.2, 1e-9);
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted) {
      result.converged = true;  // no step lowers the cost: a minimum (to the damping's resolution)
      break;
    }
    weights = cauchyWeights(trial.residual_norms_px, options, nullptr);
    // Converged when the step no longer matters: 1 us, 1e-5 rad/s, 1e-6 rad.
    const bool small = std::abs(step(kOffset)) < 1e-6 && std::abs(step(kReadout)) < 1e-6 &&
                       step.segment<3>(kBias).norm() < 1e-5 && step.segment<3>(kRotation).norm() < 1e-6;
    quiet_iterations = small ? quiet_iterations + 1 : 0;
    if (quiet_iterations >= 2) {
      result.converged = true;
      break;
    }
  }

  // ---- Uncertainty and observability. ------------------------------------------------------
  const Evaluation final_evaluation = problem.evaluate(state, weights, true);
  std::vector<ParameterVector> pair_scores;
  problem.evaluate(state, weights, true, &final_evaluation.shift_gain, &pair_scores);
  result.median_residual_px = median(final_evaluation.residual_norms_px);
  result.inlier_fraction =
      static_cast<double>(std::count_if(weights.begin(), weights.end(), [](double w) { return w > 0.5; })) /
      std::max<std::size_t>(weights.size(), 1);
  CameraImuCalibration& calibration = result.calibration;
  calibration.time_offset_s = state.time_offset_s;
  calibration.readout_time_s = state.readout_time_s;
  calibration.gyro_bias_rad_s = state.bias;
  calibration.imu_to_camera_rotation = state.R_cam_imu;
  if (n > 0) {
    ParameterMatrix H;
    ParameterVector unused_gradient;
    restrictToActive(final_evaluation, H, unused_gradient);
    // Degrees of freedom: per track, less the parameters and the eliminated nuisances.
    const double nuisance = problem.shiftUnknownCount();
    // One component per track is left when the parallax is removed, and a direction per pair
    // is spent on it.
    const double components = removesParallax(options) ? 1.0 : 2.0;
    const double parallax = removesParallax(options) ? 2.0 * refined_pairs.size() : 0.0;
    const double dof = std::max(components * final_evaluation.weight_sum - n - nuisance - parallax, 1.0);
    const double variance = final_evaluation.cost / dof;
    // A direction the data does not constrain has a (near) zero eigenvalue: its variance is
    // then effectively infinite, which the checks below turn into a refusal.
    // Scaled to a unit diagonal first, so that seconds and radians compare in the rank test.
    ParameterVector scale;
    for (int i = 0; i < kParameterCount; ++i) scale(i) = 1.0 / std::sqrt(std::max(H(i, i), 1e-300));
    const ParameterMatrix normalised = scale.asDiagonal() * H * scale.asDiagonal();
    // (SVD of the symmetric matrix: its singular vectors are its eigenvectors.)
    const Eigen::JacobiSVD<ParameterMatrix> svd(normalised, Eigen::ComputeFullU | Eigen::ComputeFullV);
    ParameterVector inverse_values;
    for (int i = 0; i < kParameterCount; ++i) {
      const double value = svd.singularValues()(i);
      inverse_values(i) = value > 1e-12 ? 1.0 / value : 1e30;
    }
    const ParameterMatrix H_inverse = scale.asDiagonal() * svd.matrixV() * inverse_values.asDiagonal() *
                                      svd.matrixU().transpose() * scale.asDiagonal();
    const ParameterMatrix covariance = variance * H_inverse;
    // Tracks of one moment share what the model misses (parallax of that moment's translation,
    // the lens shift's misfit, a tracking bias of that image content), so treating them as
    // independent overstates the information. The cluster-robust ("sandwich") covariance
    // H^-1 (sum_c s_c s_c^T) H^-1 over clusters of consecutive pairs (s_c the sum of their
    // scores) counts each stretch of the recording once; the larger of the two is reported.
    // What the model misses stays correlated for longer than 5 pairs when it comes from the scene
    // (the parallax of its layout under the hand's slow translation and pans lasts seconds): the
    // sandwich is formed for blocks of 5, 15 and 30 consecutive pairs and for sixths of the
    // recording, and each quantity takes the largest (a block length chosen conservatively, as in
    // a block bootstrap); a block length with fewer than 6 blocks is too noisy to count.
    ParameterVector sandwich_variance = ParameterVector::Zero();
    std::vector<std::size_t> block_lengths = {kPairsPerCluster, 3 * kPairsPerCluster, 6 * kPairsPerCluster,
                                              pair_scores.size() / 6};
    for (const std::size_t block : block_lengths) {
      if (block == 0 || pair_scores.size() / block < 6) continue;
      ParameterMatrix meat = ParameterMatrix::Zero();
      int clusters = 0;
      for (std::size_t start = 0; start < pair_scores.size(); start += block, ++clusters) {
        ParameterVector cluster = ParameterVector::Zero();
        for (std::size_t p = start; p < std::min(start + block, pair_scores.size()); ++p) cluster += pair_scores[p];
        for (int i = 0; i < kParameterCount; ++i) {
          if (!active[i]) cluster(i) = 0.0;
        }
        meat.noalias() += cluster * cluster.transpose();
      }
      const double small_sample = clusters > 1 ? clusters / (clusters - 1.0) : 1.0;
      const ParameterMatrix sandwich = small_sample * H_inverse * meat * H_inverse;
      sandwich_variance = sandwich_variance.cwiseMax(sandwich.diagonal());
    }
    ParameterVector statistical = ParameterVector::Zero();
    for (int i = 0; i < kParameterCount; ++i) {
      if (active[i]) statistical(i) = std::sqrt(std::max({covariance(i, i), sandwich_variance(i), 0.0}));
    }
    result.statistical.time_offset_s = statistical(kOffset);
    result.statistical.readout_time_s = statistical(kReadout);
    result.statistical.gyro_bias_rad_s = statistical.segment<3>(kBias);
    result.statistical.rotation_rad = statistical.segment<3>(kRotation);
    // The reported sigma: the statistical one inflated for the correlation it still misses, and
    // what the recording shares as a whole added in quadrature (independent of the statistical
    // part, which only sees what varies). See CalibrationOptions::statistical_sigma_factor.
    ParameterVector systematic;
    systematic(kOffset) = options.systematic_time_offset_s;
    systematic(kReadout) = options.systematic_readout_time_s;
    systematic.segment<3>(kBias).setConstant(options.systematic_gyro_bias_rad_s);
    systematic.segment<3>(kRotation).setConstant(options.systematic_rotation_rad);
    ParameterVector sigma = ParameterVector::Zero();
    for (int i = 0; i < kParameterCount; ++i) {
      if (active[i]) sigma(i) = std::hypot(options.statistical_sigma_factor * statistical(i), systematic(i));
    }
    calibration.time_offset_sigma_s = sigma(kOffset);
    calibration.readout_time_sigma_s = sigma(kReadout);
    calibration.gyro_bias_sigma_rad_s = sigma.segment<3>(kBias);
    calibration.rotation_sigma_rad = sigma.segment<3>(kRotation);
  }

  // Under OIS the usual motion advice is not enough: the lens absorbs most pan and tilt.
  const std::string ois_advice =
      options.lens_shift == LensShiftHandling::kPerFrameShift
          ? " (with OIS the lens absorbs most of the pan and tilt: record the calibration protocol, 10 s "
            "or more turning the camera briskly about all three axes, roll about the lens included, "
            "facing a scene 4 m away or more; or hold the mount at a known value, e.g. calibrated with "
            "OIS off)"
          : "";
  // Refusals judge what this recording determines: the statistical sigma (the systematic term is
  // the same for every recording; see CalibrationOptions::max_time_offset_sigma_s).
  if (options.estimate_time_offset && result.statistical.time_offset_s > options.max_time_offset_sigma_s) {
    result.refusals.push_back(
        "time offset: statistical 1-sigma " + describeSeconds(result.statistical.time_offset_s) + " exceeds " +
        describeSeconds(options.max_time_offset_sigma_s) +
        ": the rotation rate hardly changes during the recording (a steady turn looks the same at any "
        "offset); shake the camera, so that its rate changes within fractions of a second" + ois_advice);
  }
  if (options.estimate_readout_time && result.statistical.readout_time_s > options.max_readout_time_sigma_s) {
    result.refusals.push_back(
        "readout time: statistical 1-sigma " + describeSeconds(result.statistical.readout_time_s) + " exceeds " +
        describeSeconds(options.max_readout_time_sigma_s) +
        ": the top and bottom rows move alike (it needs vertical image motion, i.e. tilt about the camera x "
        "axis, roll about the optical axis, or rates that change within a frame); tilt and roll the camera "
        "while recording, or hold the readout at its known value" + ois_advice);
  }
  if (options.estimate_rotation &&
      result.statistical.rotation_rad.maxCoeff() > options.max_rotation_sigma_rad) {
    std::ostringstream why;
    why << std::fixed << std::setprecision(3) << "IMU-camera rotation: statistical 1-sigma ("
        << result.statistical.rotation_rad(0) * kRadToDeg << ", " << result.statistical.rotation_rad(1) * kRadToDeg
        << ", " << result.statistical.rotation_rad(2) * kRadToDeg << ") deg about the camera x, y, z axes exceeds "
        << options.max_rotation_sigma_rad * kRadToDeg
        << " deg: it needs clear rotation about at least two axes (gyro RMS about its principal axes "
        << rates.str() << "); turn the camera about all three axes, or hold the rotation at a known value"
        << ois_advice;
    result.refusals.push_back(why.str());
  }
  if (options.estimate_gyro_bias &&
      result.statistical.gyro_bias_rad_s.maxCoeff() > options.max_gyro_bias_sigma_rad_s) {
    std::ostringstream why;
    why << std::scientific << std::setprecision(2) << "gyro bias: statistical 1-sigma "
        << result.statistical.gyro_bias_rad_s.maxCoeff() << " rad/s exceeds " << options.max_gyro_bias_sigma_rad_s
        << " rad/s: record longer or with more texture, or hold the bias" << ois_advice;
    result.refusals.push_back(why.str());
  }
  return finish();
}
}  // namespace

std::vector<double> trackResidualsPx(const CalibrationData& data, const CameraImuCalibration& calibration,
                                     RateInterpolation interpolation) {
  const std::string camera_problem = data.camera.validate();
  if (!camera_problem.empty()) throw std::invalid_argument("track residuals: camera: " + camera_problem);
  if (data.gyro.size() < 2) throw std::invalid_argument("track residuals: needs gyro samples");
  const ImuSampleBuffer gyro = bufferOf(data.gyro);
  IntegrationOptions integration;
  integration.interpolation = interpolation;
  integration.gyro_bias_rad_s = calibration.gyro_bias_rad_s;
  const GyroOrientationTable table(gyro, integration);
  std::vector<PreparedPair> pairs;
  for (PreparedPair& pair : preparePairs(data, 1)) {
    if (table.coverage(pair.stamp_a_s + calibration.time_offset_s,
                       pair.stamp_b_s + calibration.time_offset_s + calibration.readout_time_s).ok()) {
      pairs.push_back(std::move(pair));
    }
  }
  State state;
  state.time_offset_s = calibration.time_offset_s;
  state.readout_time_s = calibration.readout_time_s;
  state.bias = calibration.gyro_bias_rad_s;
  state.R_cam_imu = calibration.imu_to_camera_rotation;
  ReprojectionProblem problem(pairs, gyro, data.camera.K(), interpolation, integration.max_sample_gap_s,
                              LensShiftHandling::kNone, 0, false);
  return problem.evaluate(state, {}, false).residual_norms_px;
}

}  // namespace deep_ois
