#include "deep_ois/net/flow_trainer.h"

#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <numeric>
#include <random>
#include <stdexcept>

#include "compensation_model_impl.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/flow/motion_history.h"
#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {

namespace {

std::vector<std::size_t> allIndices(std::size_t n) {
  std::vector<std::size_t> indices(n);
  std::iota(indices.begin(), indices.end(), 0);
  return indices;
}

// Samples with a target, the ones the loss and the validation are computed on.
std::vector<std::size_t> indicesWithTarget(const std::vector<TrainingSample>& samples) {
  std::vector<std::size_t> indices;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].hasTarget()) indices.push_back(i);
  }
  return indices;
}

// Renders the flows of samples on the working grid, one renderer per distinct camera (a training
// set has one or a few cameras), and holds the motion history of every sample.
class FlowBatcher {
 public:
  FlowBatcher(const std::vector<TrainingSample>& samples, const ModelMetadata& metadata)
      : samples_(samples), grid_(metadata.working_grid) {
    computeHistories(metadata.history_time_constants_s);
  }

  // [n, 2, H, W] tensors of the gyro and target flows of samples[indices[begin..end)], and their
  // motion histories [n, 2 * time constants, H, W] (undefined without history).
  void batch(const std::vector<std::size_t>& indices, std::size_t begin, std::size_t end, torch::Tensor& gyro,
             torch::Tensor& target, torch::Tensor& history) {
    const auto n = static_cast<int64_t>(end - begin);
    gyro = torch::empty({n, 2, grid_.height, grid_.width}, torch::kFloat32);
    target = torch::empty_like(gyro);
    std::vector<int64_t> rows;
    for (std::size_t k = begin; k < end; ++k) {
      const TrainingSample& sample = samples_[indices[k]];
      const HomographyFlowRenderer& renderer = rendererFor(sample);
      renderer.render(sample.gyro_homographies, flow_);
      gyro[static_cast<int64_t>(k - begin)] = flowToTensor(flow_)[0];
      if (sample.hasTarget()) {
        renderer.render(sample.target_homographies, flow_);
        target[static_cast<int64_t>(k - begin)] = flowToTensor(flow_)[0];
      } else {
        target[static_cast<int64_t>(k - begin)].zero_();
      }
      rows.push_back(static_cast<int64_t>(indices[k]));
    }
    history = histories_.defined() ? histories_.index_select(0, torch::tensor(rows, torch::kInt64)) : torch::Tensor();
  }

  const torch::Tensor& histories() const { return histories_; }

 private:
  // The history of each pair is what MotionHistory (as CompensationStream at run time) had summed
  // over the earlier pairs of its recording when the pair came: pairs in stamp order per recording.
  void computeHistories(const std::vector<double>& time_constants_s) {
    if (time_constants_s.empty() || samples_.empty()) return;
    const auto channels = static_cast<int64_t>(2 * time_constants_s.size());
    histories_ = torch::empty({static_cast<int64_t>(samples_.size()), channels, grid_.height, grid_.width},
                              torch::kFloat32);
    std::vector<std::size_t> order = allIndices(samples_.size());
    std::stable_sort(order.begin(), order.end(), [this](std::size_t a, std::size_t b) {
      const TrainingSample& x = samples_[a];
      const TrainingSample& y = samples_[b];
      return x.source != y.source ? x.source < y.source : x.stamp_a_ns < y.stamp_a_ns;
    });
    MotionHistory history(time_constants_s, grid_);
    const std::string* source = nullptr;
    for (std::size_t i : order) {
      const TrainingSample& sample = samples_[i];
      if (source == nullptr || *source != sample.source) history.reset();
      source = &sample.source;
      histories_[static_cast<int64_t>(i)] = historyToTensor(history.before(sample.stamp_a_ns))[0];
      rendererFor(sample).render(sample.gyro_homographies, flow_);
      history.add(sample.stamp_a_ns, sample.stamp_b_ns, flow_);
    }
  }

  const HomographyFlowRenderer& rendererFor(const TrainingSample& sample) {
    const int patches = static_cast<int>(sample.gyro_homographies.size());
    for (const auto& renderer : renderers_) {
      if (renderer->compatible(sample.camera, grid_, patches)) return *renderer;
    }
    renderers_.push_back(std::make_unique<HomographyFlowRenderer>(sample.camera, grid_, patches));
    return *renderers_.back();
  }

  const std::vector<TrainingSample>& samples_;
  cv::Size grid_;
  cv::Mat flow_;
  std::vector<std::unique_ptr<HomographyFlowRenderer>> renderers_;
  torch::Tensor histories_;
};

torch::Tensor lossOf(const torch::Tensor& prediction, const torch::Tensor& target, const std::string& loss) {
  return loss == "l2" ? torch::mse_loss(prediction, target) : torch::l1_loss(prediction, target);
}

// Mean end-point error over pixels, working-grid pixels.
double endPointError(const torch::Tensor& a, const torch::Tensor& b) {
  return (a - b).pow(2).sum(1).sqrt().mean().item<double>();
}

// Running per-channel sums of a [n, C, H, W] tensor.
struct ChannelStatistics {
  std::vector<double> sum, sum_sq;
  double count = 0;

  void add(const torch::Tensor& x) {
    const torch::Tensor channels = x.to(torch::kFloat64).transpose(0, 1).reshape({x.size(1), -1});
    const torch::Tensor s = channels.sum(1), q = channels.pow(2).sum(1);
    sum.resize(static_cast<std::size_t>(x.size(1)), 0.0);
    sum_sq.resize(sum.size(), 0.0);
    for (std::size_t c = 0; c < sum.size(); ++c) {
      sum[c] += s[static_cast<int64_t>(c)].item<double>();
      sum_sq[c] += q[static_cast<int64_t>(c)].item<double>();
    }
    count += static_cast<double>(channels.size(1));
  }
  double mean(std::size_t c) const { return sum[c] / count; }
  // A degenerate set (no motion) must not divide by zero.
  double std(std::size_t c) const {
    return std::max(std::sqrt(std::max(0.0, sum_sq[c] / count - mean(c) * mean(c))), 1e-3);
  }
};

// Per-channel mean and standard deviation of the training gyro flows and their motion histories
// (up to 2000 samples spread over the set: enough for two numbers per channel).
void computeInputStatistics(FlowBatcher& batcher, const std::vector<std::size_t>& trainable, ModelMetadata& metadata) {
  const std::size_t stride = std::max<std::size_t>(1, trainable.size() / 2000);
  std::vector<std::size_t> chosen;
  for (std::size_t i = 0; i < trainable.size(); i += stride) chosen.push_back(trainable[i]);
  ChannelStatistics flow_stats, history_stats;
  for (std::size_t begin = 0; begin < chosen.size(); begin += 64) {
    const std::size_t end = std::min(chosen.size(), begin + 64);
    torch::Tensor gyro, target, history;
    batcher.batch(chosen, begin, end, gyro, target, history);
    flow_stats.add(gyro);
    if (history.defined()) history_stats.add(history);
  }
  for (std::size_t c = 0; c < 2; ++c) {
    metadata.input_mean_px[c] = flow_stats.mean(c);
    metadata.input_std_px[c] = flow_stats.std(c);
  }
  metadata.history_mean_px.clear();
  metadata.history_std_px.clear();
  for (std::size_t c = 0; c < history_stats.sum.size(); ++c) {
    metadata.history_mean_px.push_back(history_stats.mean(c));
    metadata.history_std_px.push_back(history_stats.std(c));
  }
}

void setLearningRate(torch::optim::Adam& optimizer, double lr) {
  for (auto& group : optimizer.param_groups()) static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
}

void writeCheckpoint(const std::string& path, CompensationModel::Impl& impl, torch::optim::Adam& optimizer,
                     int epochs_done) {
  torch::serialize::OutputArchive archive;
  archive.write("deep_ois_metadata", c10::IValue(impl.metadata.toYaml()));
  torch::serialize::OutputArchive weights, optimizer_state;
  impl.net->save(weights);
  optimizer.save(optimizer_state);
  archive.write("weights", weights);
  archive.write("optimizer", optimizer_state);
  archive.write("epochs_done", c10::IValue(static_cast<int64_t>(epochs_done)));
  // Write then rename: a crash mid-write leaves the previous checkpoint intact.
  const std::string partial = path + ".partial";
  try {
    archive.save_to(partial);
  } catch (const c10::Error& e) {
    throw ModelFileError("cannot write checkpoint " + partial + ": " + e.what_without_backtrace());
  }
  if (std::rename(partial.c_str(), path.c_str()) != 0) throw ModelFileError("cannot rename " + partial + " to " + path);
}

// Restores weights, optimizer state, normalisation and history; returns the epochs already done.
int readCheckpoint(const std::string& path, CompensationModel::Impl& impl, torch::optim::Adam& optimizer) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {
    throw ModelFileError("checkpoint " + path + " is not readable: " + e.what_without_backtrace());
  }
  c10::IValue metadata_value, epochs_value;
  torch::serialize::InputArchive weights, optimizer_state;
  if (!archive.try_read("deep_ois_metadata", metadata_value) || !archive.try_read("weights", weights) ||
      !archive.try_read("optimizer", optimizer_state) || !archive.try_read("epochs_done", epochs_value)) {
    throw ModelFileError("checkpoint " + path + " lacks metadata, weights, optimizer state or epoch count");
  }
  const ModelMetadata saved = ModelMetadata::fromYaml(metadata_value.toStringRef());
  if (saved.architecture.widths != impl.metadata.architecture.widths ||
      saved.architecture.normalization != impl.metadata.architecture.normalization ||
      saved.architecture.residual != impl.metadata.architecture.residual ||
      saved.working_grid != impl.metadata.working_grid ||
      saved.history_time_constants_s != impl.metadata.history_time_constants_s) {
    throw ModelFileError("checkpoint " + path + " is of another architecture or working grid (preset " +
                         saved.preset + "); remove it or train with the same preset");
  }
  impl.metadata = saved;
  impl.net->load(weights);
  optimizer.load(optimizer_state);
  return static_cast<int>(epochs_value.toInt());
}

}  // namespace

TrainingOutcome trainCompensationModel(CompensationModel& model, const std::vector<TrainingSample>& train,
                                       const std::vector<TrainingSample>& validation, const TrainerOptions& options,
                                       const std::function<void(const TrainingProgress&)>& progress,
                                       const std::function<void(int, const TrainingRecord&)>& epoch_done) {
  if (train.empty()) throw std::invalid_argument("train: the training set is empty");
  if (options.batch_size < 1 || options.epochs < 1) throw std::invalid_argument("train: batch size and epochs must be >= 1");
  if (options.loss != "l1" && options.loss != "l2") throw std::invalid_argument("train: loss must be l1 or l2");
  if (!(options.learning_rate > 0.0) || options.lr_decay_every_epochs < 1 || !(options.lr_decay_factor > 0.0)) {
    throw std::invalid_argument("train: learning rate, its decay period and factor must be positive");
  }
  for (const auto* set : {&train, &validation}) {
    for (const TrainingSample& sample : *set) {
      if (sample.gyro_homographies.empty() ||
          (sample.hasTarget() && sample.gyro_homographies.size() != sample.target_homographies.size())) {
        throw std::invalid_argument("train: a sample from " + sample.source +
                                    " has no gyro homographies or different gyro and target patch counts");
      }
    }
  }
  const std::vector<std::size_t> trainable = indicesWithTarget(train);
  const std::vector<std::size_t> validation_indices = indicesWithTarget(validation);
  if (trainable.empty()) throw std::invalid_argument("train: no training pair has a target");

  CompensationModel::Impl& impl = model.impl();
  torch::manual_seed(options.seed);
  torch::optim::Adam optimizer(
      impl.net->parameters(),
      torch::optim::AdamOptions(options.learning_rate).betas(std::make_tuple(options.beta1, options.beta2)));

  TrainingOutcome outcome;
  int first_epoch = 0;
  if (options.resume && !options.checkpoint_path.empty() && std::ifstream(options.checkpoint_path).good()) {
    first_epoch = readCheckpoint(options.checkpoint_path, impl, optimizer);
    outcome.resumed = true;
    outcome.resumed_from_epoch = first_epoch;
  }
  // Rendered once: the motion history of every pair (a few hundred MB for the 9,000 pairs).
  FlowBatcher train_batcher(train, impl.metadata), validation_batcher(validation, impl.metadata);
  if (!outcome.resumed) {
    computeInputStatistics(train_batcher, trainable, impl.metadata);
    impl.metadata.training = TrainingRecord();
  }
  TrainingRecord& record = impl.metadata.training;
  record.train_pairs = trainable.size();
  record.validation_pairs = validation_indices.size();
  record.batch_size = options.batch_size;
  record.learning_rate = options.learning_rate;
  record.loss = options.loss;
  record.seed = options.seed;

  const std::size_t steps = (trainable.size() + options.batch_size - 1) / options.batch_size;
  const auto started = std::chrono::steady_clock::now();
  const double time_before = record.training_time_s;

  for (int epoch = first_epoch; epoch < options.epochs; ++epoch) {
    setLearningRate(optimizer, options.learning_rate *
                                   std::pow(options.lr_decay_factor, epoch / options.lr_decay_every_epochs));
    // A fresh, reproducible order per epoch (portable Fisher-Yates on the project's generator).
    std::vector<std::size_t> order = trainable;
    std::mt19937 rng = streamGenerator(options.seed, static_cast<std::uint32_t>(epoch));
    for (std::size_t i = order.size(); i > 1; --i) {
      const auto j = static_cast<std::size_t>(uniform01(rng) * static_cast<double>(i));
      std::swap(order[i - 1], order[std::min(j, i - 1)]);
    }
    impl.net->train();
    double loss_sum = 0.0;
    std::size_t step = 0;
    for (std::size_t begin = 0; begin < order.size(); begin += options.batch_size, ++step) {
      if (options.stop_requested != nullptr && options.stop_requested->load()) {
        if (!options.checkpoint_path.empty()) writeCheckpoint(options.checkpoint_path, impl, optimizer, epoch);
        impl.net->eval();
        outcome.stopped_early = true;
        outcome.epochs_done = epoch;
        return outcome;
      }
      const std::size_t end = std::min(order.size(), begin + options.batch_size);
      torch::Tensor gyro, target, history;
      train_batcher.batch(order, begin, end, gyro, target, history);
      optimizer.zero_grad();
      const torch::Tensor loss = lossOf(impl.forward(gyro, history), target, options.loss);
      loss.backward();
      optimizer.step();
      loss_sum += loss.item<double>();
      if (progress) {
        progress({epoch + 1, options.epochs, step + 1, steps, loss_sum / static_cast<double>(step + 1)});
      }
    }
    record.train_loss.push_back(loss_sum / static_cast<double>(std::max<std::size_t>(step, 1)));

    // Validation: loss, and end-point errors of the model and of the raw gyro against the target.
    impl.net->eval();
    {
      torch::NoGradGuard no_grad;
      double loss_total = 0.0, epe_total = 0.0, gyro_epe_total = 0.0;
      std::size_t batches = 0;
      for (std::size_t begin = 0; begin < validation_indices.size(); begin += 32, ++batches) {
        const std::size_t end = std::min(validation_indices.size(), begin + 32);
        torch::Tensor gyro, target, history;
        validation_batcher.batch(validation_indices, begin, end, gyro, target, history);
        const torch::Tensor prediction = impl.forward(gyro, history);
        const double weight = static_cast<double>(end - begin);
        loss_total += lossOf(prediction, target, options.loss).item<double>() * weight;
        epe_total += endPointError(prediction, target) * weight;
        gyro_epe_total += endPointError(gyro, target) * weight;
      }
      const bool none = validation_indices.empty();
      const double n = static_cast<double>(std::max<std::size_t>(validation_indices.size(), 1));
      const double nan = std::nan("");
      record.validation_loss.push_back(none ? nan : loss_total / n);
      record.validation_epe_px.push_back(none ? nan : epe_total / n);
      record.validation_gyro_epe_px.push_back(none ? nan : gyro_epe_total / n);
    }
    record.epochs = epoch + 1;
    record.training_time_s =
        time_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (!options.checkpoint_path.empty()) writeCheckpoint(options.checkpoint_path, impl, optimizer, epoch + 1);
    if (epoch_done) epoch_done(epoch + 1, record);
  }
  outcome.epochs_done = options.epochs;
  return outcome;
}

}  // namespace deep_ois
