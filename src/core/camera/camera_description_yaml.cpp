#include "deep_ois/core/camera/camera_description_yaml.h"

#include <stdexcept>
#include <string>

namespace deep_ois {
namespace {

template <typename T>
T field(const YAML::Node& map, const std::string& key, T fallback) {
  const YAML::Node value = map[key];
  if (!value) return fallback;
  try {
    return value.as<T>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument("camera." + key + " is malformed");
  }
}

}  // namespace

void writeCameraDescription(YAML::Emitter& out, const CameraDescription& camera) {
  out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width" << YAML::Value << camera.width;
  out << YAML::Key << "height" << YAML::Value << camera.height;
  out << YAML::Key << "fx" << YAML::Value << camera.fx << YAML::Key << "fy" << YAML::Value << camera.fy;
  out << YAML::Key << "cx" << YAML::Value << camera.cx << YAML::Key << "cy" << YAML::Value << camera.cy;
  if (camera.readoutKnown()) out << YAML::Key << "readout_time_s" << YAML::Value << camera.readout_time_s;
  out << YAML::Key << "frame_rate_hz" << YAML::Value << camera.frame_rate_hz;
  out << YAML::EndMap;
}

CameraDescription readCameraDescription(const YAML::Node& camera) {
  CameraDescription out;
  if (!camera) return out;
  if (!camera.IsMap()) throw std::invalid_argument("camera is not a map");
  out.width = field<int>(camera, "width", 0);
  out.height = field<int>(camera, "height", 0);
  out.fx = field<double>(camera, "fx", 0.0);
  out.fy = field<double>(camera, "fy", 0.0);
  out.cx = field<double>(camera, "cx", 0.0);
  out.cy = field<double>(camera, "cy", 0.0);
  out.readout_time_s = field<double>(camera, "readout_time_s", CameraDescription::kUnknownReadout);
  out.frame_rate_hz = field<double>(camera, "frame_rate_hz", 0.0);
  return out;
}

}  // namespace deep_ois
