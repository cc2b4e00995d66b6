#include "deep_ois/core/ground_truth/training_set_camera.h"

#include <algorithm>

namespace deep_ois {

TrainingSetCamera describeTrainingSetCamera(const std::vector<TrainingSample>& samples) {
  TrainingSetCamera out;
  std::vector<CameraDescription> distinct;
  std::vector<std::int64_t> intervals_ns;
  for (const TrainingSample& sample : samples) {
    const CameraDescription d = describeCamera(sample.camera, CameraDescription::kUnknownReadout);
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const CameraDescription& c) {
      return c.differencesTo(d).empty();
    });
    if (!seen) distinct.push_back(d);
    if (sample.stamp_b_ns > sample.stamp_a_ns) intervals_ns.push_back(sample.stamp_b_ns - sample.stamp_a_ns);
  }
  out.cameras = distinct.size();
  if (distinct.size() != 1) return out;
  out.camera = distinct.front();
  if (!intervals_ns.empty()) {
    // The median interval: a pair across a lost frame is twice as long, rare enough not to move it.
    const auto middle = intervals_ns.begin() + static_cast<std::ptrdiff_t>(intervals_ns.size() / 2);
    std::nth_element(intervals_ns.begin(), middle, intervals_ns.end());
    out.camera.frame_rate_hz = 1e9 / static_cast<double>(*middle);
  }
  return out;
}

}  // namespace deep_ois
