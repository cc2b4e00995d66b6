#include "deep_ois/ros/live/stabiliser_flow_compensator.h"

#include <Eigen/LU>
#include <cmath>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
namespace {

Eigen::Matrix3d rowMajor(const boost::array<double, 9>& values) {
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = values[static_cast<std::size_t>(3 * r + c)];
  return M;
}

// The message's rolling-shutter timing as the gyro flow nodelet used it.
RollingShutterConfig timingOf(const GyroFlow& msg) {
  RollingShutterConfig rs;
  rs.patch_count = static_cast<int>(msg.patch_count);
  rs.readout_time_s = msg.readout_time;
  rs.time_offset_s = msg.time_offset;
  rs.patch_time = msg.patch_time_fraction > 0.25 ? PatchTimeReference::kPatchCentre
                                                 : PatchTimeReference::kPatchStart;
  return rs;
}

}  // namespace

StabiliserCompensator& StabiliserFlowCompensator::compensatorFor(const GyroFlow& msg,
                                                                 std::string* problem,
                                                                 double* time_jump_back_s) {
  const Eigen::Matrix3d K = rowMajor(msg.K);
  if (!compensator_ || !K.isApprox(K_, 1e-12)) {
    compensator_ = std::make_unique<StabiliserCompensator>(model_.parameters, K);
    K_ = K;
  }
  // Before the rates: the state of another timeline must not take in this one's samples.
  const RollingShutterConfig rs = timingOf(msg);
  // A new epoch is an applied calibration: the frames' IMU times moved by the change of offset.
  const double calibration_shift_s =
      last_epoch_ && *last_epoch_ != msg.calibration_epoch ? msg.time_offset - last_time_offset_s_ : 0.0;
  last_epoch_ = msg.calibration_epoch;
  last_time_offset_s_ = msg.time_offset;
  *time_jump_back_s = compensator_->followTimeline(patchImuTime(rs, msg.previous_stamp.toSec(), 0),
                                                   patchImuTime(rs, msg.header.stamp.toSec(), 0), calibration_shift_s);
  const std::vector<CameraRateSample> rates = readGyroFlowRates(msg, problem);
  compensator_->addRates(rates);
  return *compensator_;
}

double StabiliserFlowCompensator::observe(const GyroFlow& msg) {
  std::string problem;
  double time_jump_back_s = 0.0;
  compensatorFor(msg, &problem, &time_jump_back_s);
  return time_jump_back_s;
}

StabiliserFlowResult StabiliserFlowCompensator::compensate(const GyroFlow& msg) {
  StabiliserFlowResult result;
  std::vector<Eigen::Matrix3d> gyro_homographies;
  cv::Mat gyro_flow;
  result.reason = readGyroFlowMsg(msg, gyro_homographies, gyro_flow);
  if (!result.reason.empty()) return result;
  if (msg.angular_velocity_times.empty()) {
    result.reason = "the gyro flow carries no gyro stream (angular_velocity), which the stabiliser "
                    "model needs (a gyro flow nodelet older than the model?)";
    return result;
  }
  std::string problem;
  StabiliserCompensator& compensator = compensatorFor(msg, &problem, &result.time_jump_back_s);
  if (!problem.empty()) {
    result.reason = problem;
    return result;
  }
  const RollingShutterConfig rs = timingOf(msg);
  const double stamp_a_s = msg.previous_stamp.toSec(), stamp_b_s = msg.header.stamp.toSec();
  std::vector<double> times_a, times_b;
  std::vector<Eigen::Matrix3d> rotations;
  for (int i = 0; i < rs.patch_count; ++i) {
    times_a.push_back(patchImuTime(rs, stamp_a_s, i));
    times_b.push_back(patchImuTime(rs, stamp_b_s, i));
    // The gyro's rotation back from its homography K R K^-1 (scaled to H[2][2] = 1).
    Eigen::Matrix3d R = K_.inverse() * gyro_homographies[static_cast<std::size_t>(i)] * K_;
    R /= std::cbrt(R.determinant());
    rotations.push_back(R);
  }
  const StabiliserCompensation compensation = compensator.compensate(rotations, times_a, times_b);
  if (!compensation.ok) {
    result.reason = compensation.reason;
    return result;
  }
  CameraModel camera;
  sensor_msgs::CameraInfo info;
  info.width = msg.image_width;
  info.height = msg.image_height;
  info.K = msg.K;
  info.distortion_model = msg.distortion_model;
  info.D = msg.D;
  problem = toCameraModel(info, camera);
  if (!problem.empty()) {
    result.reason = problem;
    return result;
  }
  if (!renderer_ || !renderer_->compatible(camera, gyro_flow.size(), rs.patch_count))
    renderer_ = std::make_unique<HomographyFlowRenderer>(camera, gyro_flow.size(), rs.patch_count);
  renderer_->render(compensation.homographies, result.flow);
  result.homographies = compensation.homographies;
  result.camera = camera;
  result.shift_a_px = compensation.shift_a_px;
  result.shift_b_px = compensation.shift_b_px;
  result.rotations = std::move(rotations);
  result.timing = rs;
  result.ok = true;
  return result;
}

}  // namespace deep_ois
