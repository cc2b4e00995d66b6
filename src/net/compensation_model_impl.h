// Private to src/net: the torch side of CompensationModel, shared with the trainer.
#pragma once

#include <torch/torch.h>

#include <opencv2/core.hpp>

#include "deep_ois/net/compensation_model.h"
#include "unet.h"

namespace deep_ois {

struct CompensationModel::Impl {
  ModelMetadata metadata;
  UNet net{nullptr};

  // Normalised network input from flows already on the working grid: the gyro flow
  // [batch, 2, H, W] and its motion history [batch, 2 * time constants, H, W] (undefined when the
  // model has none) -> [batch, inputChannels(), H, W].
  torch::Tensor normalise(const torch::Tensor& flow_px, const torch::Tensor& history_px) const;
  // Compensated flow (working-grid pixels) from the network output for the given input flow.
  torch::Tensor denormalise(const torch::Tensor& network_output, const torch::Tensor& input_flow_px) const;
  // Both steps around the network: flows in, compensated flows out, working-grid pixels.
  torch::Tensor forward(const torch::Tensor& flow_px, const torch::Tensor& history_px);
};

// CV_32FC2 HxW <-> [1, 2, H, W] float tensor (copies).
torch::Tensor flowToTensor(const cv::Mat& flow);
// The sums of a MotionHistory (CV_32FC2 each) -> [1, 2 * sums, H, W]; undefined for none.
torch::Tensor historyToTensor(const std::vector<cv::Mat>& sums);
cv::Mat tensorToFlow(const torch::Tensor& tensor);

}  // namespace deep_ois
