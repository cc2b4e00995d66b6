// The model the camera-IMU calibration fits (camera_imu_calibration.h): the reprojection of every
// track point through the gyro rotation between its own two capture times, over the parameters
// (time offset, readout, gyro bias, IMU-to-camera rotation) and, for an OIS camera, a lens shift
// per frame eliminated by a Schur complement. The stages (camera_imu_calibration_stages.h) and the
// track residuals evaluate it; it owns no decisions (what is estimated, when to stop, what to
// refuse). Pure Eigen.
#pragma once

#include <Eigen/Core>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/camera_imu_calibration.h"
#include "deep_ois/core/gyro/gyro_orientation_table.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"

namespace deep_ois {

// Parameter layout of the refinement: time offset (s), readout (s), bias (3, rad/s, IMU frame),
// rotation increment (3, rad, camera frame: R_cam_imu <- exp(e) R_cam_imu).
namespace calibration_parameter {
constexpr int kCount = 8;
constexpr int kOffset = 0;
constexpr int kReadout = 1;
constexpr int kBias = 2;
constexpr int kRotation = 5;
}  // namespace calibration_parameter
using CalibrationParameterVector = Eigen::Matrix<double, calibration_parameter::kCount, 1>;
using CalibrationParameterMatrix =
    Eigen::Matrix<double, calibration_parameter::kCount, calibration_parameter::kCount>;

// OIS lens shift of each frame: a translation of the image (a principal-point shift) that is a
// polynomial of the row, since the lens moves during the readout. Coefficients per power (x, y);
// storage for the cubic, powers above the configured order stay zero (only the prior sees them).
constexpr int kMaxLensShiftRowOrder = 3;
constexpr int kLensShiftCoefficients = 2 * (kMaxLensShiftRowOrder + 1);
using LensShiftCoefficients = Eigen::Matrix<double, kLensShiftCoefficients, 1>;

// Where the refinement stands.
struct CalibrationState {
  double time_offset_s = 0.0;
  double readout_time_s = 0.0;
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();  // rad/s, IMU frame
  Eigen::Matrix3d R_cam_imu = Eigen::Matrix3d::Identity();
  std::vector<LensShiftCoefficients> shifts;  // per shift block (frame), when the lens shift is modelled
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

// Undistorted pixels and rays of every track, in pairs; pairs with fewer than `min_tracks` tracks
// are left out (the caller counts what remains). Throws std::invalid_argument for a pair naming a
// frame that does not exist.
std::vector<PreparedPair> preparePairs(const CalibrationData& data, int min_tracks);

// One evaluation at a state: the cost and, when asked, the normal equations of the calibration
// parameters with the lens shifts eliminated (Schur complement), plus what recovers the shift
// step from a parameter step: shift_step = -(shift_rhs + shift_gain * parameter_step).
struct CalibrationEvaluation {
  double cost = 0.0;  // sum of w |e|^2 (px^2) plus the shift prior, at the state
  std::vector<double> residual_norms_px;  // per track, pairs in order
  double weight_sum = 0.0;
  CalibrationParameterMatrix H = CalibrationParameterMatrix::Zero();
  CalibrationParameterVector g = CalibrationParameterVector::Zero();
  Eigen::VectorXd shift_rhs;
  Eigen::MatrixXd shift_gain;
};

// The reprojection model over all prepared pairs:
//   x_b = pi(K R_b_a K^-1 (x_a - s_a(row_a))) + s_b(row_b)
// with s the lens shift of each frame (zero for a fixed lens). The gyro table is rebuilt when the
// bias changes. Keeps references to `pairs` and `gyro`: both must outlive it.
class ReprojectionProblem {
 public:
  ReprojectionProblem(const std::vector<PreparedPair>& pairs, const ImuSampleBuffer& gyro,
                      const Eigen::Matrix3d& K, RateInterpolation interpolation, double max_gap_s,
                      LensShiftHandling lens_shift, int shift_order, bool eliminate_parallax);

  std::size_t trackCount() const { return track_count_; }
  std::size_t pairCount() const { return pairs_.size(); }
  int shiftBlockCount() const { return static_cast<int>(shift_block_.size()); }
  // Shift coefficients that are estimated (the prior alone holds the others).
  int shiftUnknownCount() const { return shiftBlockCount() * 2 * (shift_order_ + 1); }

  // With `pair_scores` (needs `jacobian` and, when shifts are modelled, the `shift_gain` of an
  // evaluation at the same state): each pair's score sum_i w_i J_i^T r_i with the shifts' response
  // to the parameters folded into J, for the cluster-robust covariance. Empty `weights` = 1 each.
  CalibrationEvaluation evaluate(const CalibrationState& state, const std::vector<double>& weights, bool jacobian,
                                 const Eigen::MatrixXd* shift_gain = nullptr,
                                 std::vector<CalibrationParameterVector>* pair_scores = nullptr);

 private:
  using ShiftBlock = Eigen::Matrix<double, kLensShiftCoefficients, kLensShiftCoefficients>;
  using ShiftByParameter = Eigen::Matrix<double, kLensShiftCoefficients, calibration_parameter::kCount>;
  void eliminateShifts(const CalibrationState& state, const std::vector<ShiftBlock>& diagonal,
                       const std::map<std::pair<int, int>, ShiftBlock>& off_diagonal,
                       const std::vector<ShiftByParameter>& coupling,
                       const std::vector<LensShiftCoefficients>& gradient, CalibrationEvaluation& out) const;
  const GyroOrientationTable& tableFor(const Eigen::Vector3d& bias);

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

// Whether the options remove the parallax of camera translation (a fixed lens only; see
// CalibrationOptions::eliminate_parallax).
bool removesParallax(const CalibrationOptions& options);

// The lens shifts' part of a Gauss-Newton step, given the parameters' part (Schur back-substitution).
void applyShiftStep(CalibrationState& state, const CalibrationEvaluation& evaluation,
                    const CalibrationParameterVector& parameter_step);

// The state moved by a parameter step, the readout kept in [0, max_readout_s].
CalibrationState applyStep(const CalibrationState& state, const CalibrationParameterVector& step,
                           double max_readout_s);

// The gyro samples as a buffer (spanning all of them). Throws std::invalid_argument naming a
// sample the buffer rejects.
ImuSampleBuffer bufferOf(const std::vector<ImuSample>& gyro);

}  // namespace deep_ois
