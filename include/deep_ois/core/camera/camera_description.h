// What a trained model says about the camera it was trained for: image size, intrinsics, rolling
// shutter readout and frame rate. A model run on another camera may still work (a stabiliser model
// is in focal-length units) but the user must know: the loaders compare and warn, or refuse.
#pragma once

#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"

namespace deep_ois {

struct CameraDescription {
  int width = 0, height = 0;  // pixels; 0 = unknown (an older model)
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  // pixels
  // Rolling-shutter readout, seconds (0: global shutter); kUnknownReadout when not recorded (a
  // network trained on Fundamental Mixtures records, which do not carry it).
  static constexpr double kUnknownReadout = -1.0;
  double readout_time_s = 0.0;
  double frame_rate_hz = 0.0;  // 0 = unknown

  bool known() const { return width > 0 && height > 0; }
  bool readoutKnown() const { return readout_time_s >= 0.0; }
  // "640x480, fx 500.0 fy 500.0 cx 319.5 cy 239.5, readout 22.0 ms, 30.0 fps" ("readout unknown",
  // "frame rate unknown" for what was not recorded).
  std::string summary() const;
  // Empty when `other` is the same camera within tolerances (1 % focal, 2 % readout and frame
  // rate, 1 px principal point, exact size; what either side did not record is not compared);
  // otherwise a sentence naming each difference.
  std::string differencesTo(const CameraDescription& other) const;
};

// The size and intrinsics of `camera` with the given readout; frame rate unknown (0).
CameraDescription describeCamera(const CameraModel& camera, double readout_time_s);

// A recording's frame rate from its frame stamps (seconds, in order): 1 / the median interval, so
// that dropped frames do not lower it; 0 (unknown) with fewer than two frames.
double frameRateOfStampsHz(const std::vector<double>& stamps_s);

}  // namespace deep_ois
