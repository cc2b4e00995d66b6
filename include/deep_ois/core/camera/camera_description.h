// What a trained model says about the camera it was trained for: image size, intrinsics, rolling
// shutter readout and frame rate. A model run on another camera may still work (a stabiliser model
// is in focal-length units) but the user must know: the loaders compare and warn, or refuse.
#pragma once

#include <string>

namespace deep_ois {

struct CameraDescription {
  int width = 0, height = 0;  // pixels; 0 = unknown (an older model)
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  // pixels
  double readout_time_s = 0.0;
  double frame_rate_hz = 0.0;  // 0 = unknown

  bool known() const { return width > 0 && height > 0; }
  // "640x480, fx 500.0 fy 500.0 cx 319.5 cy 239.5, readout 22.0 ms, 30.0 fps"
  std::string summary() const;
  // Empty when `other` is the same camera within tolerances (1 % focal, 2 % readout and frame
  // rate, 1 px principal point, exact size); otherwise a sentence naming each difference.
  std::string differencesTo(const CameraDescription& other) const;
};

}  // namespace deep_ois
