// What a compensation model file says about itself: architecture, working grid, input
// normalisation and where its weights came from. Stored inside the model file (so a model can
// never be run with the wrong statistics) and written beside it as YAML for people.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "deep_ois/core/camera/camera_description.h"

namespace deep_ois {

// The UNet: `widths` are the channel counts of the encoder levels, the last one being the
// bottleneck (one max-pool between consecutive levels, so widths.size() - 1 pools).
struct UNetArchitecture {
  std::vector<int> widths;
  // "instance": conv -> InstanceNorm (no affine) -> ReLU, as the authors' network;
  // "none": conv -> ReLU. Instance normalisation makes every feature map invariant to the scale of
  // the input flow, which the authors' setting tolerates; "none" keeps the magnitude.
  std::string normalization = "none";
  // true: the network predicts a correction added to the (normalised) gyro flow; false: it predicts
  // the compensated flow itself (the authors' formulation).
  bool residual = true;
};

// Provenance of the weights, filled by the trainer (empty for an untrained model).
struct TrainingRecord {
  std::vector<std::string> data_files;
  // SHA-256 of the training-set files' bytes concatenated in data_files order, hex: check it with
  // `cat <data_files> | sha256sum`. YAML key training.data_sha256.
  std::string data_sha256;
  // Models trained before the SHA-256 carry FNV-1a 64 of the same bytes (16 hex digits) under the
  // key training.data_hash; it is read into this field (never into data_sha256, which it is not)
  // and written back under that key, so re-saving an old model keeps what it said.
  std::string legacy_data_fnv1a64;
  std::size_t train_pairs = 0;
  std::size_t validation_pairs = 0;
  int epochs = 0;
  int batch_size = 0;
  double learning_rate = 0.0;
  std::string loss;  // "l1" or "l2" (per flow component)
  unsigned seed = 0;
  // Per epoch: mean training loss, validation loss, and validation end-point error (pixels of the
  // working grid) of the model and of the uncompensated gyro input against the targets.
  std::vector<double> train_loss, validation_loss, validation_epe_px, validation_gyro_epe_px;
  double training_time_s = 0.0;
};

struct ModelMetadata {
  static constexpr int kFormatVersion = 1;

  int format_version = kFormatVersion;
  std::string preset;  // "fast", "paper" or "custom"
  UNetArchitecture architecture;
  // Size the network runs at; flows on any other grid are resampled to it and back.
  cv::Size working_grid;
  // Per-channel (u, v) statistics of the training gyro flows, in working-grid pixels: the network
  // sees (flow - mean) / std.
  std::array<double, 2> input_mean_px{{0.0, 0.0}};
  std::array<double, 2> input_std_px{{1.0, 1.0}};
  // Motion history (core/flow/motion_history.h): time constants of the leaky sums of the earlier gyro
  // flows the network sees beside the pair's own (seconds; empty = the gyro flow alone, the
  // authors' input). Two more input channels per time constant, normalised by the per-channel
  // statistics of the training set (u then v per time constant, working-grid pixels).
  std::vector<double> history_time_constants_s;
  std::vector<double> history_mean_px;
  std::vector<double> history_std_px;
  // The camera of the training set (core/ground_truth/training_set_camera.h): the compensation
  // nodelet compares it with the stream's. Unknown in models from before it was recorded, and for
  // a training set of several cameras.
  CameraDescription camera;
  TrainingRecord training;

  // Sets the history time constants with neutral statistics (mean 0, std 1 per channel) until
  // the trainer computes them; empty = the gyro flow alone.
  void setHistoryTimeConstants(const std::vector<double>& time_constants_s);
  // 2 (the gyro flow) + 2 per history time constant.
  int inputChannels() const { return 2 + 2 * static_cast<int>(history_time_constants_s.size()); }

  // Empty when usable; otherwise a sentence naming the field that is wrong.
  std::string validate() const;
  std::string toYaml() const;
  // Throws std::runtime_error naming the missing or malformed field.
  static ModelMetadata fromYaml(const std::string& yaml_text);
};

// The two presets of the README: "paper" (the authors' widths 32-64-128-256-256 with instance
// normalisation at 360x270, gyro flow input only) and "fast" (real time on a 2-core CPU, with the
// motion history of kDefaultHistoryTimeConstantsS). Throws on an unknown name.
ModelMetadata presetMetadata(const std::string& preset);

// Octave-spaced from 2 to 24 frames at 30 fps: a basis for the memories of real stabilisers'
// centring filters (corners of a few tenths of a hertz to a few hertz).
inline const std::vector<double> kDefaultHistoryTimeConstantsS = {0.05, 0.1, 0.2, 0.4, 0.8};

}  // namespace deep_ois
