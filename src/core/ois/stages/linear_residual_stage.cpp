// The linear residual stage: shift += focal_px * residual * (leaky integrals of the pan/tilt rate
// with residual_time_constants_s), fitted by ridge regression on what the chain leaves.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/linear_residual.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Adds residual * (the leaky rate integrals) to the lens.
class LinearResidualRunner final : public StabiliserStageRunner {
 public:
  LinearResidualRunner(const LinearResidualValues& p, const StabiliserModel&, const StabiliserRunContext& context)
      : residual_(p.residual), focal_px_(context.focal_px) {
    for (double tau : p.residual_time_constants_s) {
      decay_.push_back(stage_numerics::leakDecay(1.0 / tau, context.step_s));
      weight_.push_back(stage_numerics::leakWeight(1.0 / tau, context.step_s));
    }
    features_.resize(2 * static_cast<long>(decay_.size()));
  }
  void reset(StabiliserSignal&) override { state_.assign(decay_.size(), Eigen::Vector2d::Zero()); }
  void advance(StabiliserSignal& signal) override {
    const Eigen::Vector2d pan_tilt = signal.rate_rad_s.head<2>();
    const std::size_t k_count = state_.size();
    for (std::size_t k = 0; k < k_count; ++k) {
      state_[k] = decay_[k] * state_[k] + weight_[k] * pan_tilt;
      features_(static_cast<long>(k)) = state_[k].x();
      features_(static_cast<long>(k_count + k)) = state_[k].y();
    }
    if (residual_.size() != 0) signal.lens_px += focal_px_ * (residual_ * features_);
  }

 private:
  Eigen::MatrixXd residual_;
  double focal_px_;
  std::vector<double> decay_, weight_;
  std::vector<Eigen::Vector2d> state_;  // per time constant, (x, y) leaky rate integral
  Eigen::VectorXd features_;            // x's then y's
};

}  // namespace

const StabiliserStage& linearResidualStage() {
  static const StabiliserStage stage{
      "linear_residual",
      "adds a linear map (2 x 2K, unitless) of K leaky integrals of the pan/tilt rate to the lens "
      "(focal units): dynamics the chain does not name",
      false,
      true,
      {},
      {"residual_time_constants_s", "residual"},
      stage_numerics::make<LinearResidualValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const LinearResidualValues& p = valuesAs<LinearResidualValues>(own);
        out << YAML::Key << "residual_time_constants_s" << YAML::Value << YAML::Flow
            << p.residual_time_constants_s;
        std::vector<double> residual;
        for (long r = 0; r < p.residual.rows(); ++r)
          for (long c = 0; c < p.residual.cols(); ++c) residual.push_back(p.residual(r, c));
        out << YAML::Key << "residual" << YAML::Value << YAML::Flow << residual;
      },
      [](const YAML::Node& s, StageValues& own) {
        LinearResidualValues* p = &valuesAs<LinearResidualValues>(own);
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
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const LinearResidualValues& p = valuesAs<LinearResidualValues>(own);
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
      [](StageValues& own) {
        LinearResidualValues* p = &valuesAs<LinearResidualValues>(own);
        p->residual_time_constants_s.clear();
        p->residual.resize(0, 0);
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        const LinearResidualValues& p = valuesAs<LinearResidualValues>(own);
        return p.residual_time_constants_s.empty()
                   ? nullptr
                   : stage_numerics::runner<LinearResidualRunner, LinearResidualValues>(own, model, context);
      },
      [](const StageValues& own) {
        const LinearResidualValues& p = valuesAs<LinearResidualValues>(own);
        return std::string(p.residual.size() != 0 ? "linear_residual" : "");
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
