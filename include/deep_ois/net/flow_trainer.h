// Supervised training of the compensation network: gyro flow in, Fundamental Mixtures flow as
// target, both rendered on the fly on the model's working grid from the homography arrays.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "deep_ois/core/ground_truth/training_sample.h"
#include "deep_ois/net/compensation_model.h"

namespace deep_ois {

struct TrainerOptions {
  int epochs = 40;
  int batch_size = 8;              // paper: 8
  double learning_rate = 1e-4;     // paper: Adam, lr 1e-4, betas (0.9, 0.999)
  double beta1 = 0.9;
  double beta2 = 0.999;
  int lr_decay_every_epochs = 50;  // paper: lr x0.8 every 50 epochs
  double lr_decay_factor = 0.8;
  // "l1" (default: robust to the occasional bad Fundamental Mixtures target) or "l2", per flow
  // component in working-grid pixels.
  std::string loss = "l1";
  unsigned seed = 1;
  // Written after every epoch (and on stop) when non-empty: weights, optimizer state, epoch, losses.
  std::string checkpoint_path;
  // Continue from checkpoint_path when it exists.
  bool resume = false;
  // Polled between steps; when it becomes true the trainer writes the checkpoint and returns.
  const std::atomic<bool>* stop_requested = nullptr;
};

struct TrainingProgress {
  int epoch = 0;  // 1-based
  int epochs = 0;
  std::size_t step = 0;  // steps done in this epoch
  std::size_t steps_per_epoch = 0;
  double running_loss = 0.0;  // mean loss of this epoch so far
};

struct TrainingOutcome {
  int epochs_done = 0;
  bool stopped_early = false;  // stop_requested was set
  bool resumed = false;
  int resumed_from_epoch = 0;
};

// Trains `model` in place (its metadata's normalisation is computed from `train` unless resuming,
// and metadata().training is filled: losses per epoch, counts, options). `progress` is called
// after every step and `epoch_done` after every epoch (may be empty). Throws std::invalid_argument
// for an empty training set or bad options, ModelFileError for an unusable checkpoint.
TrainingOutcome trainCompensationModel(CompensationModel& model, const std::vector<TrainingSample>& train,
                                       const std::vector<TrainingSample>& validation, const TrainerOptions& options,
                                       const std::function<void(const TrainingProgress&)>& progress,
                                       const std::function<void(int epoch, const TrainingRecord&)>& epoch_done);

}  // namespace deep_ois
