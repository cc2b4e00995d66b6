#include "deep_ois/core/pipeline/frame_pair_processor.h"

#include <stdexcept>

#include "deep_ois/core/ois/lens_shift_homographies.h"

namespace deep_ois {

namespace {

// Why a lens log that was given did not cover the pair (the pair then has the gyro's motion).
std::string lensLogMiss(const LensShiftLog& log, const LensLogInterval& needed) {
  if (log.empty()) return "the log is empty";
  if (log.newestStampS() < needed.end_s) return "the log stopped before the pair's last row";
  if (log.oldestStampS() > needed.begin_s) return "the log starts after the pair's first row";
  return "a gap longer than the log's maximum gap of " + std::to_string(log.maxGapS()) + " s";
}

// The patch capture times of one frame (IMU clock, seconds), patch 0 first.
std::vector<double> patchTimes(const RollingShutterConfig& timing, double stamp_s) {
  std::vector<double> times;
  for (int i = 0; i < timing.patch_count; ++i) times.push_back(patchImuTime(timing, stamp_s, i));
  return times;
}

}  // namespace

PairGyroSpan pairGyroSpan(const RollingShutterConfig& timing, double stamp_a_s, double stamp_b_s) {
  return {patchImuTime(timing, stamp_a_s, 0) - kStabiliserWarmUpS,
          patchImuTime(timing, stamp_b_s, timing.patch_count - 1)};
}

std::vector<CameraRateSample> pairGyroStream(const ImuSampleBuffer& imu, const RollingShutterConfig& timing,
                                             double stamp_a_s, double stamp_b_s) {
  const PairGyroSpan span = pairGyroSpan(timing, stamp_a_s, stamp_b_s);
  return cameraRates(imu, timing.imu_to_camera_rotation, span.from_s, span.until_s);
}

FramePairProcessor::FramePairProcessor(const StabiliserModel& model, Timeline timeline)
    : model_(model), timeline_(timeline) {}

void FramePairProcessor::setModel(const StabiliserModel& model) {
  model_ = model;
  compensator_.reset();
}

RollingShutterHomographies FramePairProcessor::gyroMotion(const FramePair& pair) {
  if (!pair.imu || !pair.camera)
    throw std::invalid_argument("FramePairProcessor::gyroMotion: the pair has no IMU buffer or no camera");
  return computeRollingShutterHomographies(*pair.imu, pair.integration, pair.timing, pair.camera->K(),
                                           pair.stamp_a_s, pair.stamp_b_s);
}

StabiliserCompensator& FramePairProcessor::feedModel(const FramePair& pair, double* time_jump_back_s) {
  const Eigen::Matrix3d& K = pair.camera->K();
  if (!compensator_ || !K.isApprox(K_, 1e-12)) {
    compensator_ = std::make_unique<StabiliserCompensator>(*model_, K);
    K_ = K;
  }
  const double first_a_s = patchImuTime(pair.timing, pair.stamp_a_s, 0);
  const double first_b_s = patchImuTime(pair.timing, pair.stamp_b_s, 0);
  // Before the rates: the state of another timeline must not take in this one's samples.
  *time_jump_back_s = timeline_ == Timeline::kRestartWhenTimeGoesBack
                          ? compensator_->followTimeline(first_a_s, first_b_s, pair.calibration_shift_s)
                          : 0.0;
  if (pair.rates) {
    compensator_->addRates(*pair.rates);
  } else {
    const double last_b_s = patchImuTime(pair.timing, pair.stamp_b_s, pair.timing.patch_count - 1);
    compensator_->addRates(cameraRates(*pair.imu, pair.timing.imu_to_camera_rotation,
                                       compensator_->feedFrom(first_a_s), last_b_s));
  }
  return *compensator_;
}

double FramePairProcessor::observe(const FramePair& pair) {
  if (!model_) return 0.0;
  if (!pair.camera || (!pair.imu && !pair.rates))
    throw std::invalid_argument("FramePairProcessor::observe: the pair has no camera or no gyro stream");
  double time_jump_back_s = 0.0;
  feedModel(pair, &time_jump_back_s);
  return time_jump_back_s;
}

FramePairMotion FramePairProcessor::process(FramePair pair, cv::Size grid) {
  if (!pair.camera) throw std::invalid_argument("FramePairProcessor::process: the pair has no camera");
  FramePairMotion motion;
  // 1. The gyro's motion, unless the pair carries it.
  if (pair.rotations.empty()) {
    RollingShutterHomographies gyro = gyroMotion(pair);
    if (!gyro.ok()) {
      motion.gyro_status = gyro.status;
      motion.reason = gyro.reason;
      return motion;
    }
    pair.rotations = std::move(gyro.rotations);
    pair.gyro_homographies = std::move(gyro.homographies);
  }
  if (static_cast<int>(pair.rotations.size()) != pair.timing.patch_count)
    throw std::invalid_argument("FramePairProcessor::process: one gyro rotation per row patch needed");
  motion.rotations = pair.rotations;
  motion.gyro_homographies = pair.gyro_homographies;

  // 2. The lens: the log where it covers the pair, else the model, else none.
  std::optional<std::vector<Eigen::Matrix3d>> logged;
  if (pair.lens_log) {
    logged = lensLogHomographies(pair.camera->K(), pair.rotations, *pair.lens_log, pair.timing, pair.stamp_a_s,
                                 pair.stamp_b_s);
    if (!logged) motion.reason = lensLogMiss(*pair.lens_log, lensLogInterval(pair.timing, pair.stamp_a_s, pair.stamp_b_s));
  }
  if (logged) {
    motion.source = PairMotionSource::kLensLog;
    motion.homographies = std::move(*logged);
    if (model_) motion.time_jump_back_s = observe(pair);  // the model stays warm for a pair without the log
  } else if (model_) {
    if (!pair.imu && !pair.rates)
      throw std::invalid_argument("FramePairProcessor::process: the stabiliser model needs the pair's gyro stream");
    StabiliserCompensator& compensator = feedModel(pair, &motion.time_jump_back_s);
    StabiliserCompensation compensation = compensator.compensate(
        pair.rotations, patchTimes(pair.timing, pair.stamp_a_s), patchTimes(pair.timing, pair.stamp_b_s));
    if (!compensation.ok) {
      motion.reason = compensation.reason;
      return motion;
    }
    motion.source = PairMotionSource::kStabiliserModel;
    motion.homographies = std::move(compensation.homographies);
    motion.shift_a_px = std::move(compensation.shift_a_px);
    motion.shift_b_px = std::move(compensation.shift_b_px);
  } else {
    motion.homographies = pair.gyro_homographies;
  }

  // 3. The fusion with the pair's tracks: the motion above is the prior.
  if (pair.fusion && pair.tracks) fuse(pair, motion);

  // 4. The render.
  if (!grid.empty()) render(*pair.camera, grid, motion.homographies, motion.flow);
  motion.ok = true;
  return motion;
}

void FramePairProcessor::fuse(const FramePair& pair, FramePairMotion& motion) {
  motion.prior_homographies = motion.homographies;
  try {
    motion.fused = fuseMotion(*pair.camera, MotionPrior{motion.homographies, pair.prior_sigma_px}, *pair.tracks,
                              *pair.fusion);
    motion.homographies = motion.fused->homographies;
  } catch (const std::exception& e) {
    // A bad prior or option is the caller's to fix, but the pair keeps its motion meanwhile.
    motion.fused = FusedMotion();
    motion.fused->homographies = motion.prior_homographies;
    motion.fused->tracks = static_cast<int>(pair.tracks->size());
    motion.fused->sigma_px = pair.prior_sigma_px;
    motion.fused->reason = std::string("prior kept: the fusion failed: ") + e.what();
    motion.fusion_failed = true;
  }
}

void FramePairProcessor::render(const CameraModel& camera, cv::Size grid,
                                const std::vector<Eigen::Matrix3d>& homographies, cv::Mat& flow) {
  const int patch_count = static_cast<int>(homographies.size());
  if (!renderer_ || !renderer_->compatible(camera, grid, patch_count))
    renderer_ = std::make_unique<HomographyFlowRenderer>(camera, grid, patch_count);
  renderer_->render(homographies, flow);
}

}  // namespace deep_ois
