// The compensation UNet (torch; private to the net layer). Fully convolutional: any input size,
// odd ones included, gives an output of the same size.
#pragma once

#include <torch/torch.h>

#include <vector>

#include "deep_ois/net/model_metadata.h"

namespace deep_ois {

// Two 3x3 convolutions, each followed by optional instance normalisation and ReLU.
class ConvBlockImpl : public torch::nn::Module {
 public:
  ConvBlockImpl(int in_channels, int out_channels, bool instance_norm);
  torch::Tensor forward(torch::Tensor x);

 private:
  torch::nn::Sequential layers_;
};
TORCH_MODULE(ConvBlock);

class UNetImpl : public torch::nn::Module {
 public:
  // input_channels: 2 (the gyro flow) + 2 per motion-history sum (ModelMetadata::inputChannels).
  UNetImpl(const UNetArchitecture& architecture, int input_channels);
  // x: [batch, input_channels, H, W] normalised gyro flow and history -> [batch, 2, H, W].
  torch::Tensor forward(torch::Tensor x);

 private:
  std::vector<ConvBlock> encoders_;  // widths.size() levels, the last is the bottleneck
  std::vector<ConvBlock> decoders_;  // one per skip connection, deepest first
  torch::nn::Conv2d output_{nullptr};
};
TORCH_MODULE(UNet);

}  // namespace deep_ois
