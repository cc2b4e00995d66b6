// The learned lens dynamics stage: a generic lens dynamics network (core/ois/lens_dynamics_network.h)
// conditioned on this camera's vector, its lens (focal units, through the output map) added to the
// chain's. The file embeds the network, so a model file stands alone.
#include <yaml-cpp/yaml.h>

#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"

namespace deep_ois {

const StabiliserStage& learnedLensDynamicsStage() {
  static const StabiliserStage stage{
      "learned lens dynamics",
      "a recurrent network pretrained on generated stabiliser designs, conditioned on the "
      "camera's vector; its lens (focal units, through a 2 x 2 output map) is added to the chain's",
      false,
      {},
      {"learned_dynamics"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        if (!p.learned_dynamics.active()) return;
        const LearnedLensDynamics& learned = p.learned_dynamics;
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
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::optional;
        using stabiliser_file_fields::required;
        p->learned_dynamics = LearnedLensDynamics();
        if (!s["learned_dynamics"]) return;
        const YAML::Node learned = s["learned_dynamics"];
        try {
          p->learned_dynamics.network = std::make_shared<const LensDynamicsNetwork>(
              readLensDynamicsNetwork(learned["network"]));
        } catch (const LensDynamicsNetworkError& e) {
          throw StabiliserModelFileError(std::string("field 'learned_dynamics.network': ") +
                                         e.what());
        }
        const auto conditioning = required<std::vector<double>>(learned, "conditioning");
        p->learned_dynamics.conditioning = Eigen::Map<const Eigen::VectorXd>(
            conditioning.data(), static_cast<long>(conditioning.size()));
        const auto map = optional<std::vector<double>>(learned, "output_map", {1.0, 0.0, 0.0, 1.0});
        if (map.size() != 4)
          throw StabiliserModelFileError("field 'learned_dynamics.output_map' must have 4 values");
        p->learned_dynamics.output_map << map[0], map[1], map[2], map[3];
      },
      [](const StabiliserParameters& p) {
        const LearnedLensDynamics& learned = p.learned_dynamics;
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
      [](StabiliserParameters* p) { p->learned_dynamics = LearnedLensDynamics(); }};
  return stage;
}

}  // namespace deep_ois
