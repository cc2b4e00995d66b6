#include "deep_ois/core/camera/camera_description.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {
namespace {

bool relativelyClose(double a, double b, double tolerance) {
  return std::abs(a - b) <= tolerance * std::max(std::abs(a), std::abs(b));
}

}  // namespace

std::string CameraDescription::summary() const {
  if (!known()) return "unknown camera";
  char text[256];
  std::snprintf(text, sizeof(text), "%dx%d, fx %.1f fy %.1f cx %.1f cy %.1f, ", width, height, fx, fy, cx, cy);
  std::string out = text;
  if (readoutKnown()) {
    std::snprintf(text, sizeof(text), "readout %.1f ms, ", 1000.0 * readout_time_s);
    out += text;
  } else {
    out += "readout unknown, ";
  }
  if (frame_rate_hz > 0.0) {
    std::snprintf(text, sizeof(text), "%.1f fps", frame_rate_hz);
    out += text;
  } else {
    out += "frame rate unknown";
  }
  return out;
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
  if (readoutKnown() && other.readoutKnown() && !relativelyClose(readout_time_s, other.readout_time_s, 0.02))
    add("readout time differs");
  if (frame_rate_hz > 0.0 && other.frame_rate_hz > 0.0 &&
      !relativelyClose(frame_rate_hz, other.frame_rate_hz, 0.02))
    add("frame rate differs");
  return out;
}

CameraDescription describeCamera(const CameraModel& camera, double readout_time_s) {
  CameraDescription d;
  d.width = camera.width();
  d.height = camera.height();
  d.fx = camera.K()(0, 0);
  d.fy = camera.K()(1, 1);
  d.cx = camera.K()(0, 2);
  d.cy = camera.K()(1, 2);
  d.readout_time_s = readout_time_s;
  return d;
}

double frameRateOfStampsHz(const std::vector<double>& stamps_s) {
  std::vector<double> intervals;
  for (std::size_t f = 1; f < stamps_s.size(); ++f)
    intervals.push_back(stamps_s[f] - stamps_s[f - 1]);
  if (intervals.empty()) return 0.0;
  const double interval = median(std::move(intervals));
  return interval > 0.0 ? 1.0 / interval : 0.0;
}

}  // namespace deep_ois
