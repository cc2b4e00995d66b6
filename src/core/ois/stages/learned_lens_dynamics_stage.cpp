// The learned lens dynamics stage: a generic lens dynamics network (core/ois/lens_dynamics_network.h)
// conditioned on this camera's vector, its lens (focal units, through the output map) added to the
// chain's. The file embeds the network, so a model file stands alone.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/learned_lens_dynamics.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Runs the network at its own step (a whole number of internal steps, reading the rate there);
// in between, its lens is extrapolated from its last two outputs.
class LearnedLensDynamicsRunner final : public StabiliserStageRunner {
 public:
  LearnedLensDynamicsRunner(const LearnedLensDynamics& p, const StabiliserModel&, const StabiliserRunContext& context)
      : learned_(p),
        runner_(p.network, p.conditioning),
        focal_px_(context.focal_px) {
    const double network_step_s = learned_.network->step_s;
    every_steps_ = std::llround(network_step_s / context.step_s);
    if (every_steps_ < 1 ||
        std::abs(static_cast<double>(every_steps_) * context.step_s - network_step_s) > 1e-9)
      throw std::invalid_argument("stabiliser model: the learned dynamics' step (" +
                                  std::to_string(network_step_s) +
                                  " s) must be a whole number of the predictor's steps (" +
                                  std::to_string(context.step_s) + " s)");
    skip_ = learned_.network->w_skip.size() != 0;
  }
  void reset(StabiliserSignal& signal) override {
    runner_.reset();
    last_.setZero();
    before_.setZero();
    hidden_last_ = hidden_before_ =
        Eigen::VectorXd::Zero(runner_.state().size() + (skip_ ? runner_.inputs().size() : 0));
    signal.learned_state = hidden_last_;
  }
  void advance(StabiliserSignal& signal) override {
    const long long since = signal.step_index % every_steps_;
    if (since == 0) {
      before_ = last_;
      last_ = learned_.output_map * runner_.step(signal.end_rate_rad_s);
      if (signal.want_learned_state) {
        // The state the layer reads: the hidden vector, then the skip path's inputs.
        hidden_before_ = hidden_last_;
        hidden_last_.resize(runner_.state().size() + (skip_ ? runner_.inputs().size() : 0));
        hidden_last_.head(runner_.state().size()) = runner_.state();
        if (skip_) hidden_last_.tail(runner_.inputs().size()) = runner_.inputs();
      }
    }
    const double fraction = static_cast<double>(since) / static_cast<double>(every_steps_);
    signal.lens_px += focal_px_ * (last_ + fraction * (last_ - before_));
    if (signal.want_learned_state)
      signal.learned_state = hidden_last_ + fraction * (hidden_last_ - hidden_before_);
  }

 private:
  LearnedLensDynamics learned_;
  LensDynamicsRunner runner_;
  double focal_px_;
  long long every_steps_ = 1;
  bool skip_ = false;
  // Its last two outputs (focal units, through the output map) and states.
  Eigen::Vector2d last_ = Eigen::Vector2d::Zero(), before_ = Eigen::Vector2d::Zero();
  Eigen::VectorXd hidden_last_, hidden_before_;
};

}  // namespace

const StabiliserStage& learnedLensDynamicsStage() {
  static const StabiliserStage stage{
      "learned_lens_dynamics",
      "a recurrent network pretrained on generated stabiliser designs, conditioned on the "
      "camera's vector; its lens (focal units, through a 2 x 2 output map) is added to the chain's",
      false,
      true,
      {},
      {"learned_dynamics"},
      stage_numerics::make<LearnedLensDynamics>,
      [](YAML::Emitter& out, const StageValues& own) {
        const LearnedLensDynamics& p = valuesAs<LearnedLensDynamics>(own);
        if (!p.active()) return;
        const LearnedLensDynamics& learned = p;
        out << YAML::Key << "learned_dynamics" << YAML::Value << YAML::BeginMap;
        out << YAML::Key << "conditioning" << YAML::Value << YAML::Flow
            << std::vector<double>(learned.conditioning.data(),
                                   learned.conditioning.data() + learned.conditioning.size());
        out << YAML::Key << "output_map" << YAML::Value << YAML::Flow
            << stabiliser_file_fields::rowMajor(learned.output_map);
        out << YAML::Key << "network" << YAML::Value;
        writeLensDynamicsNetwork(out, *learned.network);
        out << YAML::EndMap;
      },
      [](const YAML::Node& s, StageValues& own) {
        LearnedLensDynamics* p = &valuesAs<LearnedLensDynamics>(own);
        using stabiliser_file_fields::optional;
        using stabiliser_file_fields::required;
        *p = LearnedLensDynamics();
        if (!s["learned_dynamics"]) return true;
        const YAML::Node learned = s["learned_dynamics"];
        try {
          p->network = std::make_shared<const LensDynamicsNetwork>(
              readLensDynamicsNetwork(learned["network"]));
        } catch (const LensDynamicsNetworkError& e) {
          throw StabiliserModelFileError(std::string("field 'learned_dynamics.network': ") +
                                         e.what());
        }
        const auto conditioning = required<std::vector<double>>(learned, "conditioning");
        p->conditioning = Eigen::Map<const Eigen::VectorXd>(
            conditioning.data(), static_cast<long>(conditioning.size()));
        const auto map = optional<std::vector<double>>(learned, "output_map", {1.0, 0.0, 0.0, 1.0});
        if (map.size() != 4)
          throw StabiliserModelFileError("field 'learned_dynamics.output_map' must have 4 values");
        p->output_map << map[0], map[1], map[2], map[3];
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const LearnedLensDynamics& p = valuesAs<LearnedLensDynamics>(own);
        const LearnedLensDynamics& learned = p;
        if (!learned.active()) return std::string();
        std::ostringstream why;
        if (const std::string problem = learned.network->validate(); !problem.empty()) {
          why << "learned_dynamics.network: " << problem;
        } else if (learned.conditioning.size() != learned.network->conditioning_size ||
                   !learned.conditioning.allFinite()) {
          why << "learned_dynamics.conditioning: must be " << learned.network->conditioning_size
              << " finite values (the network's conditioning_size)";
        } else if (!learned.output_map.allFinite()) {
          why << "learned_dynamics.output_map: must be finite";
        }
        return why.str();
      },
      [](StageValues& own) {
        LearnedLensDynamics* p = &valuesAs<LearnedLensDynamics>(own); *p = LearnedLensDynamics(); },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        const LearnedLensDynamics& p = valuesAs<LearnedLensDynamics>(own);
        return p.active()
                   ? stage_numerics::runner<LearnedLensDynamicsRunner, LearnedLensDynamics>(own, model, context)
                   : nullptr;
      },
      [](const StageValues& own) {
        const LearnedLensDynamics& p = valuesAs<LearnedLensDynamics>(own);
        return std::string(p.active() ? "learned_lens_dynamics" : "");
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
