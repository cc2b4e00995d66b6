// One frame pair of a training set: the gyro homography array (network input) and the
// Fundamental Mixtures rotation-only array (target). Flows are rendered from them on demand, on
// whatever grid the network works at, so training sets stay small.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera_model.h"

namespace deep_ois {

struct TrainingSample {
  CameraModel camera;
  // N homographies each, mapping undistorted camera pixels of frame a in patch i to frame b.
  std::vector<Eigen::Matrix3d> gyro_homographies;
  std::vector<Eigen::Matrix3d> target_homographies;
  std::string source;  // recording the pair came from (validation splits by recording)
};

}  // namespace deep_ois
