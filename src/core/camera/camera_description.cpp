#include "deep_ois/core/camera/camera_description.h"

#include <cmath>
#include <cstdio>

namespace deep_ois {
namespace {

bool relativelyClose(double a, double b, double tolerance) {
  return std::abs(a - b) <= tolerance * std::max(std::abs(a), std::abs(b));
}

}  // namespace

std::string CameraDescription::summary() const {
  if (!known()) return "unknown camera";
  char text[256];
  std::snprintf(text, sizeof(text),
                "%dx%d, fx %.1f fy %.1f cx %.1f cy %.1f, readout %.1f ms, %.1f fps", width, height,
                fx, fy, cx, cy, 1000.0 * readout_time_s, frame_rate_hz);
  return text;
}

std::string CameraDescription::differencesTo(const CameraDescription& other) const {
  if (!known() || !other.known()) return "";
  std::string out;
  auto add = [&](const std::string& what) { out += (out.empty() ? "" : "; ") + what; };
  if (width != other.width || height != other.height) add("image size differs");
  if (!relativelyClose(fx, other.fx, 0.01) || !relativelyClose(fy, other.fy, 0.01))
    add("focal length differs by more than 1 %");
  if (std::abs(cx - other.cx) > 1.0 || std::abs(cy - other.cy) > 1.0)
    add("principal point differs by more than 1 px");
  if (!relativelyClose(readout_time_s, other.readout_time_s, 0.02)) add("readout time differs");
  if (frame_rate_hz > 0.0 && other.frame_rate_hz > 0.0 &&
      !relativelyClose(frame_rate_hz, other.frame_rate_hz, 0.02))
    add("frame rate differs");
  return out;
}

}  // namespace deep_ois
