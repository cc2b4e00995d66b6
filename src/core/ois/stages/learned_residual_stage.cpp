// The learned residual stage: shift += focal_px * nonlinear_residual * features, the features a
// named fixed set of functions of the chain's own state (nonlinearFeatureCount), fitted by ridge
// regression in one solve.
#include <yaml-cpp/yaml.h>

#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "stabiliser_file_fields.h"

namespace deep_ois {
namespace {

constexpr const char* kKnownSets = "excursion_v1, rate_bank_v1, excursion_rate_v1";

}  // namespace

const StabiliserStage& learnedResidualStage() {
  static const StabiliserStage stage{
      "learned residual",
      "adds a linear map (2 x M) of a named set of M nonlinear features of the chain's state "
      "(excursion_v1, rate_bank_v1, excursion_rate_v1) to the lens (focal units)",
      false,
      {},
      {"nonlinear_features", "nonlinear_residual"},
      [](YAML::Emitter& out, const StabiliserParameters& p) {
        // Optional: files without it (every model before the learned nonlinear residual) still load.
        if (p.nonlinear_features.empty()) return;
        out << YAML::Key << "nonlinear_features" << YAML::Value << p.nonlinear_features;
        std::vector<double> nonlinear;
        for (long r = 0; r < p.nonlinear_residual.rows(); ++r)
          for (long c = 0; c < p.nonlinear_residual.cols(); ++c)
            nonlinear.push_back(p.nonlinear_residual(r, c));
        out << YAML::Key << "nonlinear_residual" << YAML::Value << YAML::Flow << nonlinear;
      },
      [](const YAML::Node& s, StabiliserParameters* p) {
        using stabiliser_file_fields::optional;
        p->nonlinear_features = optional<std::string>(s, "nonlinear_features", "");
        const auto nonlinear = optional<std::vector<double>>(s, "nonlinear_residual", {});
        const long m = nonlinearFeatureCount(p->nonlinear_features);
        if (!p->nonlinear_features.empty() && m == 0)
          throw StabiliserModelFileError("field 'nonlinear_features': unknown set '" +
                                         p->nonlinear_features + "' (known: " + kKnownSets + ")");
        if (static_cast<long>(nonlinear.size()) != 2 * m)
          throw StabiliserModelFileError("field 'nonlinear_residual' must have 2 x " +
                                         std::to_string(m) + " values for nonlinear_features '" +
                                         p->nonlinear_features + "'");
        p->nonlinear_residual.resize(m > 0 ? 2 : 0, m);
        for (long r = 0; r < p->nonlinear_residual.rows(); ++r)
          for (long c = 0; c < m; ++c)
            p->nonlinear_residual(r, c) = nonlinear[static_cast<std::size_t>(r * m + c)];
      },
      [](const StabiliserParameters& p) {
        std::ostringstream why;
        if (!p.nonlinear_features.empty() && nonlinearFeatureCount(p.nonlinear_features) == 0) {
          why << "nonlinear_features: unknown set '" << p.nonlinear_features << "' (known: "
              << kKnownSets << ")";
        } else if (p.nonlinear_residual.size() != 0 &&
                   (p.nonlinear_residual.rows() != 2 ||
                    p.nonlinear_residual.cols() != nonlinearFeatureCount(p.nonlinear_features) ||
                    !p.nonlinear_residual.allFinite())) {
          why << "nonlinear_residual: must be a finite 2 x "
              << nonlinearFeatureCount(p.nonlinear_features) << " matrix for nonlinear_features '"
              << p.nonlinear_features << "'";
        }
        return why.str();
      },
      [](StabiliserParameters* p) {
        p->nonlinear_features.clear();
        p->nonlinear_residual.resize(0, 0);
      }};
  return stage;
}

}  // namespace deep_ois
