#include "deep_ois/tools/support/design_trace_recording.h"

#include <algorithm>
#include <random>
#include <string>

namespace deep_ois {

Eigen::Vector2d lensAtGyroTime(const std::vector<CameraRateSample>& gyro,
                               const std::vector<Eigen::Vector2d>& lens, double t_s) {
  auto it = std::lower_bound(gyro.begin(), gyro.end(), t_s,
                             [](const CameraRateSample& s, double v) { return s.stamp_s < v; });
  if (it == gyro.begin()) return lens.front();
  if (it == gyro.end()) return lens.back();
  const std::size_t j = static_cast<std::size_t>(it - gyro.begin());
  const double alpha = (t_s - gyro[j - 1].stamp_s) / (gyro[j].stamp_s - gyro[j - 1].stamp_s);
  return (1.0 - alpha) * lens[j - 1] + alpha * lens[j];
}

StabiliserFitRecording designTraceRecording(const sim::DesignTrace& trace,
                                            const std::vector<Eigen::Vector2d>& lens,
                                            const DesignTraceCamera& camera, double noise_px,
                                            std::uint32_t noise_seed) {
  StabiliserFitRecording r;
  r.name = "design " + std::to_string(trace.design_seed) + " motion " + std::to_string(trace.motion_seed);
  r.focal_px = camera.focal_px;
  r.rates = trace.gyro;
  std::mt19937 rng(noise_seed);
  std::normal_distribution<double> noise(0.0, noise_px > 0.0 ? noise_px : 1.0);
  const double frame_s = 1.0 / camera.frame_rate_hz;
  const double end = trace.gyro.back().stamp_s - camera.readout_s - frame_s;
  for (double t = 1.0; t < end; t += frame_s) {
    for (int p = 0; p < camera.patches; ++p) {
      LensMotionObservation o;
      o.readout_fraction = (p + 0.5) / camera.patches;
      o.t_a_s = t + o.readout_fraction * camera.readout_s;
      o.t_b_s = o.t_a_s + frame_s;
      o.motion_px = lensAtGyroTime(trace.gyro, lens, o.t_b_s) - lensAtGyroTime(trace.gyro, lens, o.t_a_s);
      if (noise_px > 0.0) o.motion_px += Eigen::Vector2d(noise(rng), noise(rng));
      r.observations.push_back(o);
    }
  }
  return r;
}

}  // namespace deep_ois
