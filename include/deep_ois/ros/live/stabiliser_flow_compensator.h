// The compensation nodelet's stabiliser-model path: a GyroFlow message in, the compensated
// per-patch homographies and the compensated flow on the message's grid out. It reads the message
// into a frame pair for the frame-pair processor (core/pipeline/frame_pair_processor.h), which
// carries the learned stabiliser's state from message to message on the gyro stream the messages
// carry (GyroFlow.angular_velocity*). Torch-free.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include <deep_ois/GyroFlow.h>

namespace deep_ois {

struct StabiliserFlowResult {
  bool ok = false;
  std::string reason;  // why not, when !ok (a sentence for the drop tally)
  std::vector<Eigen::Matrix3d> homographies;  // K(s_b) R K(s_a)^-1 per patch, undistorted px (fused, with the fusion)
  // With the fusion (PairFusion): its result, and the model's homographies it started from (the
  // prior, which the per-pair check scores). Empty / nullopt without.
  std::optional<FusedMotion> fused;
  std::vector<Eigen::Matrix3d> prior_homographies;
  bool fusion_failed = false;  // the fusion threw: the prior is used, fused->reason says why
  std::vector<Eigen::Vector2d> shift_a_px, shift_b_px;
  std::vector<Eigen::Matrix3d> rotations;  // the gyro's R_b_a per patch
  RollingShutterConfig timing;             // the message's patch count, readout and time offset
  cv::Mat flow;  // CV_32FC2 on the gyro flow's grid (same convention)
  CameraModel camera;  // the message's camera (K, distortion, size) the homographies refer to
  // Seconds time went back before this message (a bag that loops): the stabiliser's state was
  // restarted from a centred lens before its gyro stream was fed. 0 when it did not.
  double time_jump_back_s = 0.0;
};

// The fusion of one pair with its tracks (the frame-pair processor's step 3).
struct PairFusion {
  const FusionOptions* options = nullptr;
  const std::vector<FeatureMatch>* tracks = nullptr;  // raw pixels of the message's camera, a -> b
  double prior_sigma_px = MotionPrior().sigma_px;
};

class StabiliserFlowCompensator {
 public:
  explicit StabiliserFlowCompensator(StabiliserModelFile model)
      : model_(std::move(model)), processor_(model_.parameters) {}

  // Feeds the message's gyro stream and compensates its pair. A message without a gyro stream (an
  // older publisher) or whose stream does not cover the pair is not ok, with the reason.
  // With `fusion`, the model's motion is refined by the pair's tracks (core/fusion/fused_motion.h).
  StabiliserFlowResult compensate(const GyroFlow& msg, const PairFusion* fusion = nullptr);
  // Feeds the message's gyro stream only (a pair without an output still moved the camera).
  // Returns how far time went back before it (seconds; 0 when it did not), as in the result.
  double observe(const GyroFlow& msg);

  const StabiliserModelFile& model() const { return model_; }
  // Another model (the online learner's swap): the stabiliser restarts from a centred lens at the
  // next message, warmed up on the gyro history it carries.
  void setModel(StabiliserModelFile model) {
    model_ = std::move(model);
    processor_.setModel(model_.parameters);
  }
  int stateResets() const { return processor_.stateResets(); }
  int timeJumps() const { return processor_.timeJumps(); }
  // Applied calibrations (GyroFlow.calibration_epoch changed) the state was carried across, and of
  // those the ones that moved back beyond the model's history (restarted).
  int calibrationChanges() const { return processor_.calibrationChanges(); }
  int calibrationRestarts() const { return processor_.calibrationRestarts(); }

 private:
  // The message's pair for the processor: its timing, camera and gyro stream (both must outlive
  // the pair) and, from a new calibration epoch, how far the applied calibration moved the frames'
  // IMU times (remembers the message's epoch).
  FramePair pairOf(const GyroFlow& msg, const CameraModel& camera, const std::vector<CameraRateSample>& rates);

  StabiliserModelFile model_;
  FramePairProcessor processor_;
  // The calibration of the last message (GyroFlow.calibration_epoch and time_offset, seconds).
  std::optional<std::uint32_t> last_epoch_;
  double last_time_offset_s_ = 0.0;
};

}  // namespace deep_ois
