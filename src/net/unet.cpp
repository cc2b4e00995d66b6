#include "unet.h"

#include <stdexcept>
#include <string>

namespace deep_ois {

namespace {
torch::nn::Conv2d conv3x3(int in_channels, int out_channels) {
  return torch::nn::Conv2d(torch::nn::Conv2dOptions(in_channels, out_channels, 3).padding(1));
}

// A convolution of the network. Without gradients (inference, validation) it goes straight to
// oneDNN (mkldnn): torch's own dispatch sends the small feature maps of the deeper levels (fewer
// than ~20k values) to its im2col path, which at one thread costs about 3x more for this network
// (4.1 vs 1.3 ms per 60x45 flow, measured; results equal to ~1e-7). Training keeps torch's path.
torch::Tensor convolve(torch::nn::Conv2dImpl& conv, const torch::Tensor& x) {
  if (torch::GradMode::is_enabled() || !at::hasMKLDNN() || x.scalar_type() != torch::kFloat32 || !x.is_contiguous() ||
      x.dim() != 4) {
    return conv.forward(x);
  }
  const auto& o = conv.options;
  const auto* padding = c10::get_if<torch::ExpandingArray<2>>(&o.padding());
  if (padding == nullptr) return conv.forward(x);  // "same"/"valid" padding: torch's path
  return at::mkldnn_convolution(x, conv.weight, conv.bias, *padding, o.stride(), o.dilation(), o.groups());
}
}  // namespace

ConvBlockImpl::ConvBlockImpl(int in_channels, int out_channels, bool instance_norm) {
  for (int i = 0; i < 2; ++i) {
    layers_->push_back(conv3x3(i == 0 ? in_channels : out_channels, out_channels));
    if (instance_norm) {
      layers_->push_back(torch::nn::InstanceNorm2d(torch::nn::InstanceNorm2dOptions(out_channels).affine(false)));
    }
    layers_->push_back(torch::nn::ReLU(torch::nn::ReLUOptions().inplace(true)));
  }
  register_module("layers", layers_);
}

torch::Tensor ConvBlockImpl::forward(torch::Tensor x) {
  for (const std::shared_ptr<torch::nn::Module>& layer : layers_->children()) {
    if (auto* conv = layer->as<torch::nn::Conv2dImpl>()) {
      x = convolve(*conv, x);
    } else if (auto* norm = layer->as<torch::nn::InstanceNorm2dImpl>()) {
      x = norm->forward(x);
    } else if (auto* relu = layer->as<torch::nn::ReLUImpl>()) {
      x = relu->forward(x);
    } else {
      throw std::logic_error("UNet: unexpected layer " + layer->name() + " in a convolution block");
    }
  }
  return x;
}

// Widths w_0..w_L (w_L the bottleneck). Decoder k (k = L-1 down to 0) takes the upsampled deeper
// features concatenated with encoder k's and gives w_(k-1) channels (w_0 at the top), the
// bilinear-upsampling UNet layout the authors use (their 32-64-128-256-256 decodes 512->128,
// 256->64, 128->32, 64->32).
UNetImpl::UNetImpl(const UNetArchitecture& architecture, int input_channels) {
  const std::vector<int>& w = architecture.widths;
  const bool instance_norm = architecture.normalization == "instance";
  const int levels = static_cast<int>(w.size());
  int in_channels = input_channels;
  for (int k = 0; k < levels; ++k) {
    encoders_.push_back(register_module("encoder" + std::to_string(k), ConvBlock(in_channels, w[k], instance_norm)));
    in_channels = w[k];
  }
  int deeper_channels = w[levels - 1];
  for (int k = levels - 2; k >= 0; --k) {
    const int out_channels = k > 0 ? w[k - 1] : w[0];
    decoders_.push_back(register_module("decoder" + std::to_string(k),
                                        ConvBlock(deeper_channels + w[k], out_channels, instance_norm)));
    deeper_channels = out_channels;
  }
  output_ = register_module("output", torch::nn::Conv2d(torch::nn::Conv2dOptions(deeper_channels, 2, 1)));
  if (architecture.residual) {
    // A residual network starts as the identity: the untrained model passes the gyro flow through
    // and training only has to learn the OIS correction.
    torch::NoGradGuard no_grad;
    output_->weight.zero_();
    output_->bias.zero_();
  }
}

torch::Tensor UNetImpl::forward(torch::Tensor x) {
  std::vector<torch::Tensor> skips;
  for (std::size_t k = 0; k < encoders_.size(); ++k) {
    if (k > 0) x = torch::max_pool2d(x, 2);
    x = encoders_[k]->forward(x);
    if (k + 1 < encoders_.size()) skips.push_back(x);
  }
  for (ConvBlock& decoder : decoders_) {
    const torch::Tensor skip = skips.back();
    skips.pop_back();
    // Upsample to the skip's exact size: odd sizes lose a row/column at each pooling step.
    x = torch::nn::functional::interpolate(
        x, torch::nn::functional::InterpolateFuncOptions()
               .size(std::vector<int64_t>{skip.size(2), skip.size(3)})
               .mode(torch::kBilinear)
               .align_corners(false));
    x = decoder->forward(torch::cat({x, skip}, 1));
  }
  return convolve(*output_, x);
}

}  // namespace deep_ois
