// The choice of how the compensation nodelet turns a gyro flow into the motion it publishes: the
// kind of compensator is chosen once from ~model, the method per pair from what the flow already
// models, and the checks may fall back to the plain gyro. CompensationRos calls these and runs the
// method chosen; no ROS or torch here.
#pragma once

#include <string>

namespace deep_ois {

// What ~model loaded (once, at start-up).
enum class CompensatorKind {
  kNetwork,          // a compensation network (.pt): the flow with the pairs' motion history
  kStabiliserModel,  // a learned stabiliser model (.yaml): the lens from the gyro stream
};

// A stabiliser model file (models/*.yaml) or a network (anything else).
CompensatorKind compensatorKindFor(const std::string& model_path);

enum class CompensationMethod {
  // The flow was made with the camera's lens-shift log (motion_model gyro+lens_log): it already is
  // the OIS camera's motion and is published as it is (the stabiliser model still follows the gyro
  // stream; the network's history restarts at the next pair without the log).
  kAsMeasured,
  kNetwork,
  kStabiliserModel,
};

// The method for one pair: as measured when the flow includes the lens log, else the compensator's.
CompensationMethod compensationMethodFor(CompensatorKind kind, bool flow_includes_lens_log);

// Whether a method compares the flow's camera with the model's (~require_matching_camera): a model
// is trained for one camera; a flow published as measured needs no model.
bool methodUsesModel(CompensationMethod method);

// Whether the stabiliser model's motion or the plain gyro's is published: the per-pair checks
// found the model worse than the gyro (`checks_fall_back`, ~fallback_to_gyro) only matters for the
// stabiliser model.
bool publishesPlainGyro(CompensationMethod method, bool checks_fall_back);

const char* toString(CompensationMethod method);

}  // namespace deep_ois
