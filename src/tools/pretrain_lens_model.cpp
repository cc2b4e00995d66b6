// Pretrains the generic lens dynamics network (the stabiliser model's learned stage) on the design
// generator's stabilisers: `pretrain_lens_model --out models/lens_dynamics_generic.yaml` rebuilds
// the shipped one (flags: `pretrain_lens_model --help`, docs/stabiliser_model.md).
#include <atomic>
#include <csignal>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/net/lens_dynamics_pretraining.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/progress_bar.h"

namespace {

std::atomic<bool> g_stop_requested{false};
void onSignal(int) { g_stop_requested = true; }

}  // namespace

constexpr char kDescription[] =
    "Pretrains the generic lens dynamics network (a GRU over the camera's gyro, conditioned on a "
    "per-camera vector) on the generated stabiliser designs of the training split (the held-out "
    "seeds, seed % 5 == 0, are never used). Writes OUT (YAML: the weights and how they were made: "
    "generator, seed ranges, iterations, loss) and, while training, OUT.checkpoint.pt and OUT as it "
    "stands every --checkpoint-every iterations; run the same command again to resume from it (Ctrl-C writes "
    "it too). Deterministic per flags. One core by default (--threads).";
constexpr char kFooter[] = "Exit status: 0 trained, 1 failed, 2 usage, 130 stopped (checkpoint written).";

int main(int argc, char** argv) {
  deep_ois::LensDynamicsPretrainingOptions options;
  std::string out;
  bool restart = false;
  deep_ois::ToolCommandLine command_line("pretrain_lens_model", kDescription, kFooter);
  CLI::App& app = command_line.app();
  app.add_option("--out", out, "the network file to write")->required()->type_name("FILE.yaml");
  command_line.addNumber("--design-seed-begin", options.design_seed_begin, "first design seed");
  command_line.addNumber("--design-seed-end", options.design_seed_end, "design seeds end (excluded)");
  command_line.addNumber("--validation-designs", options.validation_designs,
                         "the last training-split designs of the range, scored, not trained on");
  command_line.addNumber("--motions-per-design", options.motion_seeds_per_design,
                         "hand-held gyro traces per design");
  command_line.addNumber("--duration", options.trace_duration_s, "seconds per trace");
  command_line.addNumber("--motion-spread", options.motion_spread,
                         "motion amplitude factor range [1/x, x] (shake and pans drawn apart)");
  command_line.addNumber("--hidden", options.hidden_size, "GRU state size");
  command_line.addNumber("--conditioning", options.conditioning_size,
                         "per-camera conditioning vector size");
  command_line.addNumber("--step", options.step_s, "network step, seconds");
  command_line.addNumber("--batch-size", options.batch_size, "traces per iteration");
  command_line.addNumber("--iterations", options.iterations, "optimiser iterations");
  command_line.addNumber("--lr", options.learning_rate, "Adam learning rate (cosine decay)");
  command_line.addNumber("--final-lr", options.final_learning_rate, "learning rate at the end");
  command_line.addNumber("--seed", options.seed, "initial weights and batch order");
  command_line.addNumber("--threads", options.threads, "torch threads");
  command_line.addNumber("--checkpoint-every", options.checkpoint_every, "iterations between checkpoints");
  std::string integrals = "none";
  app.add_option("--integrals", integrals,
                 "time constants (s) of the leaky rate integrals fed to the network, or none")
      ->capture_default_str()
      ->type_name("none|S,S,...");
  app.add_flag("--restart", restart, "ignore an existing checkpoint and start over");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    options.input_integrals_s =
        integrals == "none" ? std::vector<double>{} : deep_ois::splitCommaSeparatedNumbers(integrals);
  } catch (const std::invalid_argument& e) {
    return command_line.usageError(std::string("--integrals: ") + e.what());
  }
  const std::string problem = options.validate();
  if (!problem.empty()) return command_line.usageError(problem);

  std::ostringstream command;
  for (int i = 0; i < argc; ++i) command << (i ? " " : "") << argv[i];
  options.command = command.str();
  options.checkpoint_path = out + ".checkpoint.pt";
  options.network_path = out;  // the network as it stands at every checkpoint
  options.resume = !restart;
  options.stop_requested = &g_stop_requested;
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    deep_ois::ProgressBar traces_bar(0, "traces"), training_bar(options.iterations, "iterations");
    std::string stage;
    const deep_ois::LensDynamicsNetwork net = deep_ois::pretrainLensDynamics(
        options, [&](const deep_ois::LensDynamicsPretrainingProgress& p) {
          if (p.stage == "traces") {
            traces_bar.setTotal(p.total);
            traces_bar.update(p.done);
            return;
          }
          char note[128];
          std::snprintf(note, sizeof(note), "loss %.4f, validation lens RMS %.5f focal", p.loss,
                        p.validation_rms_focal);
          training_bar.update(p.done, note);
        });
    net.save(out);
    const auto& record = net.provenance;
    std::printf(
        "pretrain_lens_model: wrote %s: %u designs (seeds %u-%u, training split) x %u traces of "
        "%.1f s, %llu iterations, loss %.4f, validation lens RMS %.5f focal units (%.3f px at the "
        "RE camera's focal length)\n",
        out.c_str(), record.designs, record.design_seed_begin, record.design_seed_end - 1,
        record.motion_seeds_per_design, record.trace_duration_s,
        static_cast<unsigned long long>(record.iterations), record.training_loss,
        record.validation_rms_focal, record.validation_rms_focal * record.focal_px);
    if (g_stop_requested) {
      std::fprintf(stderr, "pretrain_lens_model: stopped; run the same command to resume from %s\n",
                   options.checkpoint_path.c_str());
      return 130;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "\npretrain_lens_model: %s\n", e.what());
    return 1;
  }
  return 0;
}
