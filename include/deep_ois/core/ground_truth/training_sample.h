// One frame pair of a training set: the gyro homography array (network input) and the
// Fundamental Mixtures rotation-only array (target). Flows are rendered from them on demand, on
// whatever grid the network works at, so training sets stay small. A pair the job rejected keeps
// its gyro input without a target: the network's motion history of the next pairs needs it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"

namespace deep_ois {

struct TrainingSample {
  CameraModel camera;
  // N homographies each, mapping undistorted camera pixels of frame a in patch i to frame b.
  std::vector<Eigen::Matrix3d> gyro_homographies;
  std::vector<Eigen::Matrix3d> target_homographies;  // empty: no target (history only)
  std::string source;  // recording the pair came from (validation splits by recording)
  // Frame stamps of a and b, nanoseconds (camera clock): the order of the pairs of a recording.
  std::int64_t stamp_a_ns = 0;
  std::int64_t stamp_b_ns = 0;

  bool hasTarget() const { return !target_homographies.empty(); }
};

}  // namespace deep_ois
