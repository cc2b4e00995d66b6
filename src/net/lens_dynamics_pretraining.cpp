// Pretraining of the generic lens dynamics network: see the header. The only torch file of the
// lens model; the network it exports runs in Eigen (core/ois/lens_dynamics_network.h).
#include "deep_ois/net/lens_dynamics_pretraining.h"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/design_traces.h"

namespace deep_ois {
namespace {

constexpr const char* kGeneratorName = "deep_ois design_generator v1 (core/sim/design_generator.h)";
constexpr double kTraceFocalPx = 257.0;  // the RE camera's (the network's units do not depend on it)

// The network as torch trains it: a GRU over [rate / rate_scale, conditioning] and a linear
// output, plus one conditioning vector per training design.
struct LensDynamicsModule : torch::nn::Module {
  LensDynamicsModule(int inputs, int hidden, int conditioning, int designs)
      : gru(register_module("gru", torch::nn::GRU(torch::nn::GRUOptions(inputs + conditioning, hidden)
                                                      .batch_first(true)))),
        output(register_module("output", torch::nn::Linear(hidden, 2))),
        skip(register_module("skip", torch::nn::Linear(torch::nn::LinearOptions(inputs, 2).bias(false)))),
        codes(register_module("codes", torch::nn::Embedding(designs, conditioning))) {
    torch::nn::init::normal_(codes->weight, 0.0, 0.01);
  }
  // inputs [B, T, I] (scaled rates and integrals), conditioning [B, C] -> lens [B, T, 2] (output
  // units): a readout of the GRU's state plus the skip path.
  torch::Tensor forward(const torch::Tensor& inputs, const torch::Tensor& conditioning) {
    const auto steps = inputs.size(1);
    torch::Tensor input =
        torch::cat({inputs, conditioning.unsqueeze(1).expand({-1, steps, -1})}, 2);
    return output->forward(std::get<0>(gru->forward(input))) + skip->forward(inputs);
  }
  torch::nn::GRU gru;
  torch::nn::Linear output;
  torch::nn::Linear skip;
  torch::nn::Embedding codes;
};

struct TraceSet {
  torch::Tensor rates;    // [N, T, 3], rate / rate_scale
  torch::Tensor lens;     // [N, T, 2], focal units / output_scale
  torch::Tensor design;   // [N], index of the design's code (training set only)
  std::vector<std::uint32_t> design_seeds;  // per trace
};

// Linear interpolation of samples (stamps increasing) at t.
template <typename Sample, typename Value>
Value interpolateAt(const std::vector<double>& stamps, const std::vector<Sample>& values, double t,
                    Value zero) {
  if (stamps.empty()) return zero;
  auto it = std::lower_bound(stamps.begin(), stamps.end(), t);
  if (it == stamps.begin()) return values.front();
  if (it == stamps.end()) return values.back();
  const std::size_t j = static_cast<std::size_t>(it - stamps.begin());
  const double alpha = (t - stamps[j - 1]) / (stamps[j] - stamps[j - 1]);
  return (1.0 - alpha) * values[j - 1] + alpha * values[j];
}

double logUniform(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> u(-std::log(spread), std::log(spread));
  return std::exp(u(rng));
}

// The design traces of `seeds` (motion seeds 1..motion_seeds_per_design each), resampled on the
// network's steps t_n = (n + 1) step_s.
TraceSet makeTraces(const std::vector<std::uint32_t>& seeds, const LensDynamicsPretrainingOptions& o,
                    double rate_scale, double output_scale,
                    const std::function<void(std::uint64_t, std::uint64_t)>& tick) {
  const long steps = static_cast<long>(std::floor(o.trace_duration_s / o.step_s + 1e-9)) - 1;
  const long traces = static_cast<long>(seeds.size() * o.motion_seeds_per_design);
  const long k_count = static_cast<long>(o.input_integrals_s.size());
  std::vector<double> decay, weight;  // the leaky integrals per network step, as the runner's
  for (double tau : o.input_integrals_s) {
    decay.push_back(std::exp(-o.step_s / tau));
    weight.push_back(tau * (1.0 - decay.back()));
  }
  TraceSet set;
  set.rates = torch::zeros({traces, steps, 3 + 2 * k_count});
  set.lens = torch::zeros({traces, steps, 2});
  set.design = torch::zeros({traces}, torch::kLong);
  auto rates = set.rates.accessor<float, 3>();
  auto lens = set.lens.accessor<float, 3>();
  auto design = set.design.accessor<long, 1>();
  long index = 0;
  for (std::size_t d = 0; d < seeds.size(); ++d) {
    for (std::uint32_t m = 1; m <= o.motion_seeds_per_design; ++m, ++index) {
      sim::DesignTraceOptions trace_options;
      trace_options.duration_s = o.trace_duration_s;
      trace_options.focal_px = kTraceFocalPx;
      // The motion's amplitude drawn per trace (deterministic in the design and motion seeds).
      std::mt19937 rng(seeds[d] * 7919u + m);
      const double shake = logUniform(rng, o.motion_spread), pan = logUniform(rng, o.motion_spread);
      trace_options.motion.shake_rms_rad_s *= shake;
      trace_options.motion.shake_peak_rad_s *= shake;
      trace_options.motion.pan_peak_rad_s *= pan;
      const sim::DesignTrace trace = sim::simulateDesignTrace(seeds[d], m, trace_options);
      std::vector<double> stamps;
      std::vector<Eigen::Vector3d> gyro;
      for (const CameraRateSample& s : trace.gyro) {
        stamps.push_back(s.stamp_s);
        gyro.push_back(s.rate_rad_s);
      }
      std::vector<double> integrals(static_cast<std::size_t>(2 * k_count), 0.0);
      for (long n = 0; n < steps; ++n) {
        const double t = trace.gyro.front().stamp_s + static_cast<double>(n + 1) * o.step_s;
        const Eigen::Vector3d w =
            interpolateAt(stamps, gyro, t, Eigen::Vector3d(Eigen::Vector3d::Zero()));
        const Eigen::Vector2d s = interpolateAt(stamps, trace.lens_px, t,
                                                Eigen::Vector2d(Eigen::Vector2d::Zero()));
        for (int k = 0; k < 3; ++k) rates[index][n][k] = static_cast<float>(w(k) / rate_scale);
        for (long k = 0; k < k_count; ++k)
          for (int axis = 0; axis < 2; ++axis) {
            double& integral = integrals[static_cast<std::size_t>(axis * k_count + k)];
            integral = decay[k] * integral + weight[k] * w(axis);
            rates[index][n][3 + axis * k_count + k] = static_cast<float>(integral / output_scale);
          }
        for (int k = 0; k < 2; ++k)
          lens[index][n][k] = static_cast<float>(s(k) / trace_options.focal_px / output_scale);
      }
      design[index] = static_cast<long>(d);
      set.design_seeds.push_back(seeds[d]);
      if (tick) tick(static_cast<std::uint64_t>(index + 1), static_cast<std::uint64_t>(traces));
    }
  }
  return set;
}

Eigen::MatrixXd toEigen(const torch::Tensor& tensor) {
  const torch::Tensor t = tensor.detach().to(torch::kDouble).contiguous();
  const long rows = t.size(0), cols = t.dim() > 1 ? t.size(1) : 1;
  Eigen::MatrixXd m(rows, cols);
  const torch::Tensor matrix = t.reshape({rows, cols});
  auto a = matrix.accessor<double, 2>();
  for (long r = 0; r < rows; ++r)
    for (long c = 0; c < cols; ++c) m(r, c) = a[r][c];
  return m;
}

LensDynamicsNetwork exportNetwork(LensDynamicsModule& module, const LensDynamicsPretrainingOptions& o,
                                  double rate_scale, double output_scale) {
  LensDynamicsNetwork net;
  net.hidden_size = o.hidden_size;
  net.conditioning_size = o.conditioning_size;
  net.step_s = o.step_s;
  net.rate_scale_rad_s = rate_scale;
  net.output_scale = output_scale;
  net.w_input = toEigen(module.gru->named_parameters()["weight_ih_l0"]);
  net.w_hidden = toEigen(module.gru->named_parameters()["weight_hh_l0"]);
  net.b_input = toEigen(module.gru->named_parameters()["bias_ih_l0"]);
  net.b_hidden = toEigen(module.gru->named_parameters()["bias_hh_l0"]);
  net.input_integrals_s = o.input_integrals_s;
  net.w_output = toEigen(module.output->weight);
  net.w_skip = toEigen(module.skip->weight);
  net.b_output = toEigen(module.output->bias);
  const torch::Tensor codes = module.codes->weight.detach();
  net.default_conditioning = toEigen(codes.mean(0));
  net.conditioning_spread = toEigen(codes.std(0) + 1e-4);
  return net;
}

// RMS lens error (focal units) of the exported network with its default conditioning on `set`,
// in Eigen (what the pipeline runs); and the largest difference to torch's output on the first
// trace (the export must reproduce the trained network).
double validationRms(const LensDynamicsNetwork& exported, LensDynamicsModule& module,
                     const TraceSet& set, double* max_torch_difference) {
  auto network = std::make_shared<const LensDynamicsNetwork>(exported);
  auto rates = set.rates.accessor<float, 3>();
  auto lens = set.lens.accessor<float, 3>();
  double sum = 0.0;
  std::size_t count = 0;
  torch::Tensor first;
  {
    torch::NoGradGuard no_grad;
    torch::Tensor c = torch::from_blob(const_cast<double*>(exported.default_conditioning.data()),
                                       {1, exported.conditioning_size}, torch::kDouble)
                          .to(torch::kFloat);
    first = module.forward(set.rates.slice(0, 0, 1), c).squeeze(0);
  }
  auto first_a = first.accessor<float, 2>();
  *max_torch_difference = 0.0;
  for (long i = 0; i < set.rates.size(0); ++i) {
    LensDynamicsRunner runner(network, exported.default_conditioning);
    for (long n = 0; n < set.rates.size(1); ++n) {
      const Eigen::Vector3d w(rates[i][n][0], rates[i][n][1], rates[i][n][2]);
      const Eigen::Vector2d y = runner.step(w * exported.rate_scale_rad_s);
      const Eigen::Vector2d truth(lens[i][n][0], lens[i][n][1]);
      sum += (y - truth * exported.output_scale).squaredNorm();
      ++count;
      if (i == 0)
        for (int k = 0; k < 2; ++k)
          *max_torch_difference = std::max(
              *max_torch_difference, std::abs(y(k) / exported.output_scale - first_a[n][k]));
    }
  }
  return count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
}

}  // namespace

std::string LensDynamicsPretrainingOptions::validate() const {
  std::ostringstream why;
  if (design_seed_end <= design_seed_begin) why << "design seeds: the range is empty";
  else if (motion_seeds_per_design < 1) why << "motion_seeds_per_design: must be at least 1";
  else if (!(trace_duration_s >= 1.0)) why << "trace_duration_s: must be at least 1 s";
  else if (!(motion_spread >= 1.0)) why << "motion_spread: must be >= 1";
  else if (hidden_size < 1 || conditioning_size < 0) why << "hidden_size, conditioning_size: out of range";
  else if (!(step_s > 0.0 && step_s < 0.05)) why << "step_s: must be in (0, 0.05) s";
  else if (batch_size < 1 || iterations < 1) why << "batch_size, iterations: must be positive";
  else if (!(learning_rate > 0.0) || !(final_learning_rate > 0.0)) why << "learning rates: must be positive";
  else if (!(motion_lag_s >= step_s)) why << "motion_lag_s: must be at least one step";
  else if (threads < 1) why << "threads: must be at least 1";
  else if (checkpoint_every < 1) why << "checkpoint_every: must be positive";
  else
    for (double tau : input_integrals_s)
      if (!(tau > 0.0)) {
        why << "input_integrals_s: must be positive";
        break;
      }
  return why.str();
}

std::string LensDynamicsPretrainingOptions::signature() const {
  std::ostringstream s;
  s << "designs " << design_seed_begin << "-" << design_seed_end << " validation " << validation_designs
    << " motions " << motion_seeds_per_design << " duration " << trace_duration_s << " spread "
    << motion_spread << " hidden " << hidden_size << " conditioning " << conditioning_size << " step "
    << step_s << " batch " << batch_size << " iterations " << iterations << " lr " << learning_rate
    << "-" << final_learning_rate << " motion " << motion_lag_s << "x" << motion_loss_weight
    << " penalty " << conditioning_penalty << " seed " << seed;
  if (!input_integrals_s.empty()) {
    s << " integrals";
    for (double tau : input_integrals_s) s << " " << tau;
  }
  return s.str();
}

LensDynamicsNetwork pretrainLensDynamics(
    const LensDynamicsPretrainingOptions& o,
    const std::function<void(const LensDynamicsPretrainingProgress&)>& progress) {
  const std::string problem = o.validate();
  if (!problem.empty()) throw std::invalid_argument("pretraining: " + problem);
  torch::set_num_threads(o.threads);
  torch::manual_seed(o.seed);
  const double rate_scale = 0.5;     // rad/s: hand-held rates are a few tenths
  const double output_scale = 0.01;  // focal units: strokes are about a degree (0.017)

  std::vector<std::uint32_t> seeds;
  for (std::uint32_t s = o.design_seed_begin; s < o.design_seed_end; ++s)
    if (sim::designSplit(s) == sim::DesignSplit::kTraining) seeds.push_back(s);
  if (seeds.size() <= o.validation_designs)
    throw std::invalid_argument("pretraining: the seed range holds " + std::to_string(seeds.size()) +
                                " training designs, not more than validation_designs");
  const std::vector<std::uint32_t> validation_seeds(seeds.end() - o.validation_designs, seeds.end());
  seeds.resize(seeds.size() - o.validation_designs);

  std::uint64_t total_traces = (seeds.size() + validation_seeds.size()) * o.motion_seeds_per_design;
  auto tick_offset = [&](std::uint64_t offset) {
    return [&, offset](std::uint64_t done, std::uint64_t) {
      if (progress) progress({"traces", offset + done, total_traces, 0.0, 0.0});
    };
  };
  const TraceSet training = makeTraces(seeds, o, rate_scale, output_scale, tick_offset(0));
  const TraceSet validation = makeTraces(validation_seeds, o, rate_scale, output_scale,
                                         tick_offset(seeds.size() * o.motion_seeds_per_design));

  auto module = std::make_shared<LensDynamicsModule>(
      3 + 2 * static_cast<int>(o.input_integrals_s.size()), o.hidden_size, o.conditioning_size,
      static_cast<int>(seeds.size()));
  torch::optim::Adam optimizer(module->parameters(), torch::optim::AdamOptions(o.learning_rate));
  std::uint64_t iteration = 0;
  double recent_loss = 0.0, validation_rms = 0.0;
  if (!o.checkpoint_path.empty() && o.resume && std::filesystem::exists(o.checkpoint_path)) {
    try {
      torch::serialize::InputArchive archive;
      archive.load_from(o.checkpoint_path);
      c10::IValue signature, done;
      archive.read("signature", signature);
      if (signature.toStringRef() == o.signature()) {
        module->load(archive);
        torch::serialize::InputArchive optimizer_archive;
        archive.read("optimizer", optimizer_archive);
        optimizer.load(optimizer_archive);
        archive.read("iteration", done);
        iteration = static_cast<std::uint64_t>(done.toInt());
        c10::IValue loss;
        if (archive.try_read("recent_loss", loss)) recent_loss = loss.toDouble();
      }
    } catch (const c10::Error& e) {
      throw std::runtime_error(o.checkpoint_path + ": cannot resume from this checkpoint (" +
                               e.what_without_backtrace() + "); remove it to start over");
    }
  }
  auto checkpoint = [&]() {
    if (o.checkpoint_path.empty()) return;
    torch::serialize::OutputArchive archive;
    module->save(archive);
    torch::serialize::OutputArchive optimizer_archive;
    optimizer.save(optimizer_archive);
    archive.write("optimizer", optimizer_archive);
    archive.write("signature", c10::IValue(o.signature()));
    archive.write("iteration", c10::IValue(static_cast<int64_t>(iteration)));
    archive.write("recent_loss", c10::IValue(recent_loss));
    const std::string partial = o.checkpoint_path + ".partial";
    try {
      archive.save_to(partial);
    } catch (const c10::Error& e) {
      throw std::runtime_error(o.checkpoint_path + ": cannot write the checkpoint (" +
                               e.what_without_backtrace() + ")");
    }
    std::filesystem::rename(partial, o.checkpoint_path);
  };

  auto finished = [&](double validation_rms_focal) {
    LensDynamicsNetwork net = exportNetwork(*module, o, rate_scale, output_scale);
    net.provenance.generator = kGeneratorName;
    net.provenance.design_seed_begin = o.design_seed_begin;
    net.provenance.design_seed_end = o.design_seed_end;
    net.provenance.designs = static_cast<std::uint32_t>(seeds.size());
    net.provenance.motion_seeds_per_design = o.motion_seeds_per_design;
    net.provenance.trace_duration_s = o.trace_duration_s;
    net.provenance.focal_px = kTraceFocalPx;
    net.provenance.iterations = iteration;
    net.provenance.training_loss = recent_loss;
    net.provenance.validation_rms_focal = validation_rms_focal;
    net.provenance.command = o.command;
    return net;
  };
  const long lag = std::max(1L, static_cast<long>(std::lround(o.motion_lag_s / o.step_s)));
  const long traces = training.rates.size(0);
  double max_torch_difference = 0.0;
  while (iteration < o.iterations) {
    if (o.stop_requested && o.stop_requested->load()) break;
    // The batch of this iteration: deterministic in (seed, iteration), so a resumed run draws
    // what the uninterrupted one would have.
    std::mt19937 rng(o.seed * 1000003u + static_cast<unsigned>(iteration));
    std::uniform_int_distribution<long> pick(0, traces - 1);
    std::vector<long> rows(static_cast<std::size_t>(o.batch_size));
    for (long& r : rows) r = pick(rng);
    const torch::Tensor index = torch::tensor(rows, torch::kLong);
    const double progress_fraction = static_cast<double>(iteration) / static_cast<double>(o.iterations);
    const double lr = o.final_learning_rate +
                      0.5 * (o.learning_rate - o.final_learning_rate) * (1.0 + std::cos(M_PI * progress_fraction));
    for (auto& group : optimizer.param_groups())
      static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);

    const torch::Tensor rates = training.rates.index_select(0, index);
    const torch::Tensor target = training.lens.index_select(0, index);
    const torch::Tensor codes = module->codes->forward(training.design.index_select(0, index));
    const torch::Tensor lens = module->forward(rates, codes);
    const torch::Tensor motion = lens.slice(1, lag) - lens.slice(1, 0, -lag);
    const torch::Tensor target_motion = target.slice(1, lag) - target.slice(1, 0, -lag);
    torch::Tensor loss = torch::mse_loss(lens, target) +
                         o.motion_loss_weight * torch::mse_loss(motion, target_motion) +
                         o.conditioning_penalty * codes.pow(2).mean();
    optimizer.zero_grad();
    loss.backward();
    torch::nn::utils::clip_grad_norm_(module->parameters(), 1.0);
    optimizer.step();
    ++iteration;
    const double value = loss.item<double>();
    recent_loss = iteration == 1 ? value : 0.98 * recent_loss + 0.02 * value;
    if (iteration % o.checkpoint_every == 0 || iteration == o.iterations) {
      validation_rms = validationRms(exportNetwork(*module, o, rate_scale, output_scale), *module,
                                     validation, &max_torch_difference);
      checkpoint();
      if (!o.network_path.empty()) finished(validation_rms).save(o.network_path);
    }
    if (progress) progress({"training", iteration, o.iterations, recent_loss, validation_rms});
  }
  checkpoint();
  LensDynamicsNetwork net = finished(0.0);
  net.provenance.validation_rms_focal = validationRms(net, *module, validation, &max_torch_difference);
  // The export must be the trained network: torch's and Eigen's outputs on a validation trace.
  if (max_torch_difference > 1e-3)
    throw std::runtime_error("pretraining: the exported network differs from torch's by " +
                             std::to_string(max_torch_difference) + " output units");
  return net;
}

}  // namespace deep_ois
