// The trained compensation network behind a torch-free interface: callers (nodelet, evaluator,
// benchmark, tests) pass OpenCV flows and never include torch.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "deep_ois/net/model_metadata.h"

namespace deep_ois {

// A model file that is missing, unreadable, not a deep_ois model, or incompatible with this
// build. what() names the file and the problem.
class ModelFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CompensationModel {
 public:
  // A freshly initialised network (weights from `seed`) with this metadata; throws
  // std::invalid_argument when the metadata does not validate.
  explicit CompensationModel(const ModelMetadata& metadata, unsigned seed = 1);
  ~CompensationModel();
  CompensationModel(CompensationModel&&) noexcept;
  CompensationModel& operator=(CompensationModel&&) noexcept;

  // Reads a model written by save(): metadata and weights. Throws ModelFileError.
  static CompensationModel load(const std::string& path);
  // Writes metadata and weights to `path` (one file). Throws ModelFileError when it cannot.
  void save(const std::string& path) const;

  const ModelMetadata& metadata() const;
  ModelMetadata& metadata();

  // The compensated flow for a gyro flow: CV_32FC2 on any grid, in that grid's pixels; the result
  // has the same size and unit. Internally resampled to the working grid and back. `history`: the
  // motion-history sums before the pair (MotionHistory::before on the working grid), exactly as
  // many as metadata().history_time_constants_s; a stream of pairs goes through CompensationStream,
  // which keeps them. Throws std::invalid_argument for a malformed flow or history.
  cv::Mat compensate(const cv::Mat& gyro_flow, const std::vector<cv::Mat>& history = {}) const;

  // Opaque access for the trainer (src/net only).
  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  explicit CompensationModel(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Intra-op threads torch may use for inference and training (process-wide).
void setTorchThreads(int threads);

}  // namespace deep_ois
