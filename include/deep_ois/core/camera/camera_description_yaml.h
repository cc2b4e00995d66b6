// The `camera` map of the model files: a learned stabiliser model (core/ois/
// stabiliser_model_file.h) and the compensation network's metadata (net/model_metadata.h) say
// which camera they were trained for in the same words.
//
//   camera: {width: 640, height: 480, fx: 500, fy: 500, cx: 319.5, cy: 239.5,
//            readout_time_s: 0.022, frame_rate_hz: 30}
//
// readout_time_s is absent when it was not recorded; frame_rate_hz 0 when unknown; width and
// height 0 for a model trained on several cameras (a generic one).
#pragma once

#include <yaml-cpp/yaml.h>

#include "deep_ois/core/camera/camera_description.h"

namespace deep_ois {

// Emits the key `camera` and its map into the open map of `out`.
void writeCameraDescription(YAML::Emitter& out, const CameraDescription& camera);

// Reads the map; an absent node is an unknown camera. Throws std::invalid_argument naming the
// malformed field ("camera.fx is malformed").
CameraDescription readCameraDescription(const YAML::Node& camera);

}  // namespace deep_ois
