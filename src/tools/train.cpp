// Trains the compensation network on training-set bags of the Fundamental Mixtures job (flags:
// `train --help`, docs/command_line_tools.md).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/ground_truth/training_set_camera.h"
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/flow_trainer.h"
#include "deep_ois/ros/bag/training_set_reader.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/dataset_hash.h"
#include "deep_ois/tools/support/csv_plot.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

std::atomic<bool> g_stop_requested{false};
void onSignal(int) { g_stop_requested = true; }

// Whole recordings go to validation (pairs of one recording are correlated): a seeded choice of
// ceil(fraction * recordings) of them; with a single recording, its last pairs.
void splitByRecording(const std::vector<deep_ois::TrainingSample>& all, double fraction,
                      unsigned seed, std::vector<deep_ois::TrainingSample>& train,
                      std::vector<deep_ois::TrainingSample>& validation) {
  std::vector<std::string> sources;
  for (const auto& sample : all) {
    if (std::find(sources.begin(), sources.end(), sample.source) == sources.end())
      sources.push_back(sample.source);
  }
  if (fraction <= 0.0) {
    train = all;
    return;
  }
  if (sources.size() < 2) {
    const auto cut = static_cast<std::size_t>(static_cast<double>(all.size()) * (1.0 - fraction));
    train.assign(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(cut));
    validation.assign(all.begin() + static_cast<std::ptrdiff_t>(cut), all.end());
    return;
  }
  std::sort(sources.begin(), sources.end());
  std::mt19937 rng = deep_ois::streamGenerator(seed, 7777);
  for (std::size_t i = sources.size(); i > 1; --i) {
    const auto j = static_cast<std::size_t>(deep_ois::uniform01(rng) * static_cast<double>(i));
    std::swap(sources[i - 1], sources[std::min(j, i - 1)]);
  }
  const auto held_out =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(fraction * sources.size())));
  const std::set<std::string> validation_sources(
      sources.begin(), sources.begin() + static_cast<std::ptrdiff_t>(held_out));
  for (const auto& sample : all)
    (validation_sources.count(sample.source) ? validation : train).push_back(sample);
}

std::string stripSuffix(const std::string& path, const std::string& suffix) {
  if (path.size() > suffix.size() &&
      path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return path.substr(0, path.size() - suffix.size());
  }
  return path;
}

}  // namespace

constexpr char kDescription[] =
    "Trains the compensation network on training-set bags of the Fundamental Mixtures job. Writes "
    "NAME.pt (weights + metadata, with the SHA-256 of the training bags), NAME.yaml (the metadata, "
    "for people), NAME_loss.csv and NAME_loss.png and, during training, NAME.checkpoint.pt (after every epoch; "
    "Ctrl-C "
    "writes it too; --resume goes on from it). Losses and errors are in working-grid pixels.";
constexpr char kFooter[] =
    "Exit status: 0 trained, 1 failed, 2 usage, 130 stopped (checkpoint written).";

int main(int argc, char** argv) {
  std::vector<std::string> data;
  std::string out, preset = "fast";
  deep_ois::TrainerOptions options;
  double validation_fraction = 0.1;
  int threads = 2;
  std::size_t max_pairs = 0;
  std::string history = "preset";
  std::vector<int> widths;
  deep_ois::ToolCommandLine command_line("train", kDescription, kFooter);
  CLI::App& app = command_line.app();
  app.add_option("--data", data, "training-set bags (fundamental_mixtures output)")
      ->required()
      ->type_name("FILE.bag");
  app.add_option("--out", out, "the model file, e.g. models/NAME.pt")
      ->required()
      ->type_name("FILE.pt");
  app.add_option("--preset", preset, "architecture and working grid")
      ->check(deep_ois::oneOf({"fast", "paper"}))
      ->capture_default_str()
      ->type_name("fast|paper");
  command_line.addNumber("--epochs", options.epochs, "training epochs");
  command_line.addNumber("--batch-size", options.batch_size, "frame pairs per step (paper: 8)");
  command_line.addNumber("--lr", options.learning_rate, "Adam learning rate (paper: 1e-4)");
  command_line.addNumber("--beta1", options.beta1, "Adam beta1");
  command_line.addNumber("--beta2", options.beta2, "Adam beta2");
  command_line.addNumber("--lr-decay-epochs", options.lr_decay_every_epochs,
                         "multiply the learning rate by --lr-decay-factor every this many epochs");
  command_line.addNumber("--lr-decay-factor", options.lr_decay_factor,
                         "learning-rate decay factor");
  app.add_option("--loss", options.loss, "per flow component, working-grid pixels")
      ->check(deep_ois::oneOf({"l1", "l2"}))
      ->capture_default_str()
      ->type_name("l1|l2");
  command_line.addNumber("--validation-fraction", validation_fraction,
                         "share of the recordings held out for validation, in [0, 1)");
  command_line.addNumber("--seed", options.seed, "initial weights, split and batch order");
  command_line.addNumber("--threads", threads, "torch threads");
  app.add_flag("--resume", options.resume, "go on from NAME.checkpoint.pt");
  command_line.addNumber("--max-pairs", max_pairs, "use at most this many pairs (0: all)");
  // The motion history's time constants in seconds, or none (the gyro flow alone).
  app.add_option("--history", history,
                 "motion-history time constants in seconds, or none (the gyro flow alone); "
                 "default: the preset's")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            if (text == "none") return {};
            try {
              deep_ois::splitCommaSeparatedNumbers(text);
              return {};
            } catch (const std::invalid_argument& e) {
              return "needs none or comma-separated seconds, got '" + text + "' (" + e.what() + ")";
            }
          },
          ""))
      ->type_name("none|S,S,...");
  // The UNet's level widths instead of the preset's (the preset becomes "custom").
  app.add_option("--widths", widths,
                 "UNet level widths instead of the preset's (preset becomes custom)")
      ->delimiter(',')
      ->check(deep_ois::strictNumber<int>())
      ->type_name("W,W,...");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (validation_fraction < 0.0 || validation_fraction >= 1.0) {
    return command_line.usageError("--validation-fraction must be in [0, 1)");
  }

  const std::string stem = stripSuffix(out, ".pt");
  options.checkpoint_path = stem + ".checkpoint.pt";
  try {
    deep_ois::setTorchThreads(threads);
    deep_ois::ModelMetadata metadata = deep_ois::presetMetadata(preset);
    if (!widths.empty()) {
      metadata.architecture.widths = widths;
      metadata.preset = "custom";
    }
    if (history != "preset") {
      metadata.setHistoryTimeConstants(history == "none"
                                           ? std::vector<double>{}
                                           : deep_ois::splitCommaSeparatedNumbers(history));
    }
    deep_ois::CompensationModel model(metadata, options.seed);

    const deep_ois::TrainingSet set = deep_ois::readTrainingSet(data);
    std::fprintf(stderr,
                 "train: %zu records in %zu bag(s), %zu with a target, %zu more for the motion "
                 "history only\n",
                 set.records, data.size(), set.with_target, set.samples.size() - set.with_target);
    for (const auto& [reason, count] : set.skipped_by_reason)
      std::fprintf(stderr, "  skipped %zu: %s\n", count, reason.c_str());
    std::vector<deep_ois::TrainingSample> samples = set.samples;
    if (max_pairs > 0 && samples.size() > max_pairs) samples.resize(max_pairs);
    // The model says which camera it is for; the compensation nodelet compares it with the stream.
    const deep_ois::TrainingSetCamera trained_for = deep_ois::describeTrainingSetCamera(samples);
    if (trained_for.cameras == 1) {
      std::fprintf(stderr, "train: camera %s\n", trained_for.camera.summary().c_str());
    } else {
      std::fprintf(stderr, "train: the training set holds %zu cameras: the model records none (a generic model)\n",
                   trained_for.cameras);
    }
    std::vector<deep_ois::TrainingSample> train, validation;
    splitByRecording(samples, validation_fraction, options.seed, train, validation);
    std::fprintf(stderr,
                 "train: %zu training pairs, %zu validation pairs, preset %s (working grid %dx%d, "
                 "%zu motion-history "
                 "sums), %d threads\n",
                 train.size(), validation.size(), model.metadata().preset.c_str(),
                 model.metadata().working_grid.width, model.metadata().working_grid.height,
                 model.metadata().history_time_constants_s.size(), threads);

    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    options.stop_requested = &g_stop_requested;
    std::unique_ptr<deep_ois::ProgressBar> bar;
    int bar_first_epoch = -1;
    auto on_step = [&](const deep_ois::TrainingProgress& p) {
      if (!bar) {  // created at the first step, so a resumed run counts only what is left
        bar_first_epoch = p.epoch;
        bar = std::make_unique<deep_ois::ProgressBar>(
            static_cast<std::size_t>(p.epochs - p.epoch + 1) * p.steps_per_epoch, "steps");
      }
      char note[96];
      std::snprintf(note, sizeof(note), "epoch %d/%d, loss %.4f", p.epoch, p.epochs,
                    p.running_loss);
      bar->update(static_cast<std::size_t>(p.epoch - bar_first_epoch) * p.steps_per_epoch + p.step,
                  note);
    };
    auto on_epoch = [&](int epoch, const deep_ois::TrainingRecord& record) {
      std::fprintf(
          stderr,
          "\ntrain: epoch %d: train loss %.4f, validation loss %.4f, validation EPE %.4f px "
          "(gyro input %.4f px), working-grid pixels\n",
          epoch, record.train_loss.back(), record.validation_loss.back(),
          record.validation_epe_px.back(), record.validation_gyro_epe_px.back());
    };
    const deep_ois::TrainingOutcome outcome =
        deep_ois::trainCompensationModel(model, train, validation, options, on_step, on_epoch);
    if (outcome.resumed)
      std::fprintf(stderr, "train: resumed after epoch %d\n", outcome.resumed_from_epoch);
    if (outcome.stopped_early) {
      std::fprintf(stderr,
                   "\ntrain: stopped after %d epochs; checkpoint %s (continue with --resume)\n",
                   outcome.epochs_done, options.checkpoint_path.c_str());
      return 130;
    }

    deep_ois::TrainingRecord& record = model.metadata().training;
    record.data_files = data;
    record.data_sha256 = deep_ois::sha256OfFiles(data);
    model.metadata().camera = trained_for.camera;
    model.save(out);
    std::ofstream yaml(stem + ".yaml");
    yaml << "# Metadata of " << out << " (also stored inside it).\n" << model.metadata().toYaml();
    if (!yaml) throw std::runtime_error("cannot write " + stem + ".yaml");
    std::vector<double> epochs(record.train_loss.size());
    std::iota(epochs.begin(), epochs.end(), 1.0);
    deep_ois::CsvPlot plot;
    plot.title = "deep_ois " + model.metadata().preset + ": " + options.loss + " loss per epoch";
    plot.x_column = plot.x_label = "epoch";
    plot.y_labels = {"loss [px]"};
    plot.curves = {{"train_loss_px", "training loss"}, {"validation_loss_px", "validation loss"}};
    plot.log_y = true;
    const deep_ois::PlotOutcome plot_outcome = deep_ois::writeAndPlotCsv(
        plot, {{"epoch", epochs}, {"train_loss_px", record.train_loss}, {"validation_loss_px", record.validation_loss}},
        stem + "_loss.csv", stem + "_loss.png");
    std::printf("train: wrote %s, %s.yaml after %d epochs, %.0f s of training; %s\n", out.c_str(), stem.c_str(),
                record.epochs, record.training_time_s,
                deep_ois::describePlot(plot_outcome, stem + "_loss.csv", stem + "_loss.png").c_str());
    if (!record.validation_epe_px.empty()) {
      std::printf("train: validation EPE %.4f px vs gyro input %.4f px (working grid %dx%d)\n",
                  record.validation_epe_px.back(), record.validation_gyro_epe_px.back(),
                  model.metadata().working_grid.width, model.metadata().working_grid.height);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "\ntrain: %s\n", e.what());
    return 1;
  }
  return 0;
}
