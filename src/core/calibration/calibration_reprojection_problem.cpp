#include "deep_ois/core/calibration/calibration_reprojection_problem.h"

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

namespace {

// The layout's names, short, as the formulas below use them.
constexpr int kParameterCount = calibration_parameter::kCount;
using calibration_parameter::kBias;
using calibration_parameter::kOffset;
using calibration_parameter::kReadout;
using calibration_parameter::kRotation;
using ParameterVector = CalibrationParameterVector;
using ParameterMatrix = CalibrationParameterMatrix;
using State = CalibrationState;
using Evaluation = CalibrationEvaluation;
constexpr int kShiftCount = kLensShiftCoefficients;
using ShiftVector = LensShiftCoefficients;
using ShiftBasis = Eigen::Matrix<double, 2, kShiftCount>;
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

}  // namespace

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

ReprojectionProblem::ReprojectionProblem(const std::vector<PreparedPair>& pairs, const ImuSampleBuffer& gyro,
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

Evaluation ReprojectionProblem::evaluate(const State& state, const std::vector<double>& weights, bool jacobian,
                                         const Eigen::MatrixXd* shift_gain,
                                         std::vector<ParameterVector>* pair_scores) {
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

// Schur complement of the (block-banded, sparse) shift unknowns.
void ReprojectionProblem::eliminateShifts(const State& state, const std::vector<ShiftBlock>& diagonal,
                                          const std::map<std::pair<int, int>, ShiftBlock>& off_diagonal,
                                          const std::vector<ShiftByParameter>& coupling,
                                          const std::vector<ShiftVector>& gradient, Evaluation& out) const {
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

const GyroOrientationTable& ReprojectionProblem::tableFor(const Eigen::Vector3d& bias) {
  if (!table_ || bias != table_bias_) {
    integration_.gyro_bias_rad_s = bias;
    table_ = std::make_unique<GyroOrientationTable>(gyro_, integration_);
    table_bias_ = bias;
  }
  return *table_;
}

bool removesParallax(const CalibrationOptions& options) {
  return options.eliminate_parallax && options.lens_shift == LensShiftHandling::kNone;
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

ImuSampleBuffer bufferOf(const std::vector<ImuSample>& gyro) {
  const double span = gyro.back().stamp_s - gyro.front().stamp_s;
  ImuSampleBuffer buffer(span + 1.0);
  for (const ImuSample& sample : gyro) {
    const ImuAddResult added = buffer.add(sample);
    if (!added.accepted()) throw std::invalid_argument("calibration: gyro: " + added.reason);
  }
  return buffer;
}

}  // namespace deep_ois
