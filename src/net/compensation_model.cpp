#include "deep_ois/net/compensation_model.h"

#include <torch/torch.h>

#include <fstream>
#include <map>
#include <sstream>

#include "compensation_model_impl.h"
#include "deep_ois/core/flow/flow_resample.h"

namespace deep_ois {

namespace {

constexpr const char* kMetadataKey = "deep_ois_metadata";
constexpr const char* kWeightsKey = "weights";

std::string shapeText(const at::IntArrayRef& sizes) {
  std::ostringstream out;
  out << sizes;
  return out.str();
}

}  // namespace

torch::Tensor CompensationModel::Impl::normalise(const torch::Tensor& flow_px, const torch::Tensor& history_px) const {
  const auto options = flow_px.options();
  const torch::Tensor mean =
      torch::tensor({metadata.input_mean_px[0], metadata.input_mean_px[1]}, options).view({1, 2, 1, 1});
  const torch::Tensor std_px =
      torch::tensor({metadata.input_std_px[0], metadata.input_std_px[1]}, options).view({1, 2, 1, 1});
  const torch::Tensor flow = (flow_px - mean) / std_px;
  const auto history_channels = static_cast<int64_t>(metadata.history_mean_px.size());
  if (history_channels == 0) return flow;
  if (!history_px.defined() || history_px.size(1) != history_channels) {
    throw std::invalid_argument("compensation model: the motion history needs " + std::to_string(history_channels) +
                                " channels");
  }
  const torch::Tensor history_mean = torch::tensor(metadata.history_mean_px, options).view({1, history_channels, 1, 1});
  const torch::Tensor history_std = torch::tensor(metadata.history_std_px, options).view({1, history_channels, 1, 1});
  return torch::cat({flow, (history_px - history_mean) / history_std}, 1);
}

torch::Tensor CompensationModel::Impl::denormalise(const torch::Tensor& network_output,
                                                   const torch::Tensor& input_flow_px) const {
  const auto options = network_output.options();
  const torch::Tensor mean =
      torch::tensor({metadata.input_mean_px[0], metadata.input_mean_px[1]}, options).view({1, 2, 1, 1});
  const torch::Tensor std_px =
      torch::tensor({metadata.input_std_px[0], metadata.input_std_px[1]}, options).view({1, 2, 1, 1});
  // Residual: the output is a correction in units of the input spread, added to the gyro flow.
  if (metadata.architecture.residual) return input_flow_px + network_output * std_px;
  return network_output * std_px + mean;
}

torch::Tensor CompensationModel::Impl::forward(const torch::Tensor& flow_px, const torch::Tensor& history_px) {
  return denormalise(net->forward(normalise(flow_px, history_px)), flow_px);
}

torch::Tensor flowToTensor(const cv::Mat& flow) {
  CV_Assert(flow.type() == CV_32FC2);
  const cv::Mat contiguous = flow.isContinuous() ? flow : flow.clone();
  // HxWx2 interleaved -> 1x2xHxW planar.
  return torch::from_blob(const_cast<float*>(contiguous.ptr<float>()), {1, flow.rows, flow.cols, 2}, torch::kFloat32)
      .permute({0, 3, 1, 2})
      .contiguous();
}

torch::Tensor historyToTensor(const std::vector<cv::Mat>& sums) {
  if (sums.empty()) return torch::Tensor();
  std::vector<torch::Tensor> channels;
  channels.reserve(sums.size());
  for (const cv::Mat& sum : sums) channels.push_back(flowToTensor(sum));
  return torch::cat(channels, 1);
}

cv::Mat tensorToFlow(const torch::Tensor& tensor) {
  const torch::Tensor hwc = tensor.detach().to(torch::kFloat32).squeeze(0).permute({1, 2, 0}).contiguous();
  cv::Mat flow(static_cast<int>(hwc.size(0)), static_cast<int>(hwc.size(1)), CV_32FC2);
  std::memcpy(flow.data, hwc.data_ptr<float>(), flow.total() * flow.elemSize());
  return flow;
}

CompensationModel::CompensationModel(const ModelMetadata& metadata, unsigned seed) : impl_(std::make_unique<Impl>()) {
  const std::string problem = metadata.validate();
  if (!problem.empty()) throw std::invalid_argument("compensation model: " + problem);
  torch::manual_seed(seed);
  impl_->metadata = metadata;
  impl_->net = UNet(metadata.architecture, metadata.inputChannels());
  impl_->net->eval();
}

CompensationModel::CompensationModel(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CompensationModel::~CompensationModel() = default;
CompensationModel::CompensationModel(CompensationModel&&) noexcept = default;
CompensationModel& CompensationModel::operator=(CompensationModel&&) noexcept = default;

const ModelMetadata& CompensationModel::metadata() const { return impl_->metadata; }
ModelMetadata& CompensationModel::metadata() { return impl_->metadata; }

void CompensationModel::save(const std::string& path) const {
  try {
    torch::serialize::OutputArchive archive;
    archive.write(kMetadataKey, c10::IValue(impl_->metadata.toYaml()));
    torch::serialize::OutputArchive weights;
    impl_->net->save(weights);
    archive.write(kWeightsKey, weights);
    archive.save_to(path);
  } catch (const c10::Error& e) {
    throw ModelFileError("cannot write model file " + path + ": " + e.what_without_backtrace());
  }
}

CompensationModel CompensationModel::load(const std::string& path) {
  if (!std::ifstream(path).good()) throw ModelFileError("model file " + path + " does not exist or cannot be read");
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {
    throw ModelFileError("model file " + path + " is not a torch archive (corrupt or truncated?): " +
                         e.what_without_backtrace());
  }
  c10::IValue metadata_value;
  if (!archive.try_read(kMetadataKey, metadata_value) || !metadata_value.isString()) {
    throw ModelFileError("model file " + path + " has no deep_ois metadata: not a deep_ois compensation model");
  }
  auto impl = std::make_unique<Impl>();
  try {
    impl->metadata = ModelMetadata::fromYaml(metadata_value.toStringRef());
  } catch (const std::exception& e) {
    throw ModelFileError("model file " + path + ": " + e.what());
  }
  impl->net = UNet(impl->metadata.architecture, impl->metadata.inputChannels());
  // InputArchive replaces tensors without comparing shapes: check them against the architecture
  // the metadata describes, so a mismatch is an error here and not garbage later.
  std::map<std::string, std::vector<int64_t>> expected;
  for (const auto& item : impl->net->named_parameters()) expected[item.key()] = item.value().sizes().vec();
  torch::serialize::InputArchive weights;
  if (!archive.try_read(kWeightsKey, weights)) throw ModelFileError("model file " + path + " has no weights");
  try {
    impl->net->load(weights);
  } catch (const c10::Error& e) {
    throw ModelFileError("model file " + path + ": weights do not match the architecture in its metadata: " +
                         e.what_without_backtrace());
  }
  for (const auto& item : impl->net->named_parameters()) {
    if (item.value().sizes().vec() != expected[item.key()]) {
      throw ModelFileError("model file " + path + ": weight '" + item.key() + "' has shape " +
                           shapeText(item.value().sizes()) + " but the architecture needs " +
                           shapeText(expected[item.key()]));
    }
    if (!torch::isfinite(item.value()).all().item<bool>()) {
      throw ModelFileError("model file " + path + ": weight '" + item.key() + "' holds NaN or inf");
    }
  }
  impl->net->eval();
  return CompensationModel(std::move(impl));
}

cv::Mat CompensationModel::compensate(const cv::Mat& gyro_flow, const std::vector<cv::Mat>& history) const {
  if (gyro_flow.type() != CV_32FC2 || gyro_flow.empty()) {
    throw std::invalid_argument("compensate: the gyro flow must be a non-empty CV_32FC2 image");
  }
  const ModelMetadata& m = impl_->metadata;
  if (history.size() != m.history_time_constants_s.size()) {
    throw std::invalid_argument("compensate: the model takes " + std::to_string(m.history_time_constants_s.size()) +
                                " motion-history sums, got " + std::to_string(history.size()) +
                                " (use CompensationStream)");
  }
  for (const cv::Mat& sum : history) {
    if (sum.type() != CV_32FC2 || sum.size() != m.working_grid) {
      throw std::invalid_argument("compensate: motion-history sums must be CV_32FC2 on the working grid");
    }
  }
  const cv::Mat input = resampleFlow(gyro_flow, m.working_grid);
  // Inference mode: no autograd bookkeeping at all (cheaper than NoGradGuard for small tensors).
  c10::InferenceMode inference;
  const torch::Tensor output = impl_->forward(flowToTensor(input), historyToTensor(history));
  return resampleFlow(tensorToFlow(output), gyro_flow.size());
}

void setTorchThreads(int threads) {
  if (threads < 1) throw std::invalid_argument("torch threads must be at least 1");
  torch::set_num_threads(threads);
}

}  // namespace deep_ois
