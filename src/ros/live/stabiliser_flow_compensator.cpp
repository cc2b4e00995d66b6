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

// The message's rolling-shutter timing as the gyro flow nodelet used it (its rates are in the
// camera frame already: the IMU-to-camera rotation stays the identity).
RollingShutterConfig timingOf(const GyroFlow& msg) {
  RollingShutterConfig rs;
  rs.patch_count = static_cast<int>(msg.patch_count);
  rs.readout_time_s = msg.readout_time;
  rs.time_offset_s = msg.time_offset;
  rs.patch_time = msg.patch_time_fraction > 0.25 ? PatchTimeReference::kPatchCentre
                                                 : PatchTimeReference::kPatchStart;
  return rs;
}

// The message's camera. When its distortion cannot be read (*problem set), a camera of its K alone:
// enough to carry the stabiliser's state, not to render.
CameraModel cameraOf(const GyroFlow& msg, std::string* problem) {
  sensor_msgs::CameraInfo info;
  info.width = msg.image_width;
  info.height = msg.image_height;
  info.K = msg.K;
  info.distortion_model = msg.distortion_model;
  info.D = msg.D;
  CameraModel camera;
  *problem = toCameraModel(info, camera);
  if (!problem->empty())
    camera = CameraModel(static_cast<int>(msg.image_width), static_cast<int>(msg.image_height), rowMajor(msg.K));
  return camera;
}

}  // namespace

FramePair StabiliserFlowCompensator::pairOf(const GyroFlow& msg, const CameraModel& camera,
                                            const std::vector<CameraRateSample>& rates) {
  FramePair pair;
  pair.stamp_a_s = msg.previous_stamp.toSec();
  pair.stamp_b_s = msg.header.stamp.toSec();
  pair.timing = timingOf(msg);
  pair.camera = &camera;
  pair.rates = &rates;
  // A new epoch is an applied calibration: the frames' IMU times moved by the change of offset.
  pair.calibration_shift_s =
      last_epoch_ && *last_epoch_ != msg.calibration_epoch ? msg.time_offset - last_time_offset_s_ : 0.0;
  last_epoch_ = msg.calibration_epoch;
  last_time_offset_s_ = msg.time_offset;
  return pair;
}

double StabiliserFlowCompensator::observe(const GyroFlow& msg) {
  std::string camera_problem, rates_problem;
  const CameraModel camera = cameraOf(msg, &camera_problem);
  const std::vector<CameraRateSample> rates = readGyroFlowRates(msg, &rates_problem);
  return processor_.observe(pairOf(msg, camera, rates));
}

StabiliserFlowResult StabiliserFlowCompensator::compensate(const GyroFlow& msg, const PairFusion* fusion) {
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
  std::string camera_problem, rates_problem;
  const CameraModel camera = cameraOf(msg, &camera_problem);
  const std::vector<CameraRateSample> rates = readGyroFlowRates(msg, &rates_problem);
  FramePair pair = pairOf(msg, camera, rates);
  // A message that cannot be compensated still carries the gyro stream the lens moved with.
  if (!rates_problem.empty() || !camera_problem.empty()) {
    result.time_jump_back_s = processor_.observe(pair);
    result.reason = !rates_problem.empty() ? rates_problem : camera_problem;
    return result;
  }
  // The gyro's rotation back from its homography K R K^-1 (scaled to H[2][2] = 1).
  const Eigen::Matrix3d K = camera.K(), K_inverse = K.inverse();
  for (const Eigen::Matrix3d& H : gyro_homographies) {
    Eigen::Matrix3d R = K_inverse * H * K;
    R /= std::cbrt(R.determinant());
    pair.rotations.push_back(R);
  }
  pair.gyro_homographies = gyro_homographies;
  if (fusion) {
    pair.fusion = fusion->options;
    pair.tracks = fusion->tracks;
    pair.prior_sigma_px = fusion->prior_sigma_px;
  }
  FramePairMotion motion = processor_.process(std::move(pair), gyro_flow.size());
  result.time_jump_back_s = motion.time_jump_back_s;
  if (!motion.ok) {
    result.reason = motion.reason;
    return result;
  }
  result.homographies = std::move(motion.homographies);
  result.flow = motion.flow;
  result.camera = camera;
  result.shift_a_px = std::move(motion.shift_a_px);
  result.shift_b_px = std::move(motion.shift_b_px);
  result.rotations = std::move(motion.rotations);
  result.fused = std::move(motion.fused);
  result.prior_homographies = std::move(motion.prior_homographies);
  result.fusion_failed = motion.fusion_failed;
  result.timing = timingOf(msg);
  result.ok = true;
  return result;
}

}  // namespace deep_ois
