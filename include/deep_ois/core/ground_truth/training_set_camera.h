// Which camera a training set was recorded with, for the metadata of the network trained on it
// ("a trained model says which camera it is for"): the size and intrinsics of its pairs and the
// frame rate of their median interval. The Fundamental Mixtures records do not carry the
// rolling-shutter readout, so it stays unknown.
#pragma once

#include <cstddef>
#include <vector>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/ground_truth/training_sample.h"

namespace deep_ois {

struct TrainingSetCamera {
  // Unknown (known() false) when the pairs come from several cameras: a generic model.
  CameraDescription camera;
  // Distinct cameras among the pairs (same size, focal lengths within 1 %, principal point
  // within 1 px count as one).
  std::size_t cameras = 0;
};

TrainingSetCamera describeTrainingSetCamera(const std::vector<TrainingSample>& samples);

}  // namespace deep_ois
