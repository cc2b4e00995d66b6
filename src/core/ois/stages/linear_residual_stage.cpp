// The linear residual stage: shift += focal_px * residual * (leaky integrals of the pan/tilt rate
// with residual_time_constants_s), fitted by ridge regression on what the chain leaves.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"

namespace deep_ois {

const StabiliserStage& linearResidualStage() {
  static const StabiliserStage stage{
      "linear residual",
      "adds a linear map (2 x 2K, unitless) of K leaky integrals of the pan/tilt rate to the lens "
      "(focal units): dynamics the chain does not name",
      false,
      {},
      {"residual_time_constants_s", "residual"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        out << YAML::Key << "residual_time_constants_s" << YAML::Value << YAML::Flow
            << p.residual_time_constants_s;
        std::vector<double> residual;
        for (long r = 0; r < p.residual.rows(); ++r)
          for (long c = 0; c < p.residual.cols(); ++c) residual.push_back(p.residual(r, c));
        out << YAML::Key << "residual" << YAML::Value << YAML::Flow << residual;
      },
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::optional;
        p->residual_time_constants_s =
            optional<std::vector<double>>(s, "residual_time_constants_s", {});
        const auto residual = optional<std::vector<double>>(s, "residual", {});
        const long k = static_cast<long>(p->residual_time_constants_s.size());
        if (static_cast<long>(residual.size()) != 4 * k)
          throw StabiliserModelFileError(
              "field 'residual' must have 4 values per residual time constant");
        p->residual.resize(k > 0 ? 2 : 0, 2 * k);
        for (long r = 0; r < p->residual.rows(); ++r)
          for (long c = 0; c < p->residual.cols(); ++c)
            p->residual(r, c) = residual[static_cast<std::size_t>(r * 2 * k + c)];
      },
      [](const StabiliserParameters& p) {
        std::ostringstream why;
        if (p.residual.size() != 0 &&
            (p.residual.rows() != 2 ||
             p.residual.cols() != 2 * static_cast<long>(p.residual_time_constants_s.size()) ||
             !p.residual.allFinite())) {
          why << "residual: must be a finite 2 x " << 2 * p.residual_time_constants_s.size()
              << " matrix (2 x 2 per residual time constant)";
          return why.str();
        }
        for (double tau : p.residual_time_constants_s) {
          if (!(std::isfinite(tau) && tau > 0.0)) {
            why << "residual_time_constants_s: must be positive (got " << tau << ")";
            break;
          }
        }
        return why.str();
      },
      [](StabiliserParameters* p) {
        p->residual_time_constants_s.clear();
        p->residual.resize(0, 0);
      }};
  return stage;
}

}  // namespace deep_ois
