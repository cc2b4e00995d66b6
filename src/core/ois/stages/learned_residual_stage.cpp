// The learned residual stage: shift += focal_px * nonlinear_residual * features, the features a
// named fixed set of functions of the chain's own state (nonlinearFeatureCount), fitted by ridge
// regression in one solve.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <sstream>

#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/learned_residual.h"
#include "deep_ois/core/ois/stages/stroke.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

constexpr const char* kKnownSets = "excursion_v1, rate_bank_v1, excursion_rate_v1";

// The excursion_v1 set: 10 features per axis (see the runner).
constexpr int kExcursionFeaturesPerAxis = 10;
// Leaky integrals of the excursion-weighted command (seconds).
constexpr double kExcursionIntegralTimeConstantsS[] = {0.03, 0.15, 0.6};
// Excursions beyond this many strokes are not weighted further (keeps the powers bounded when a
// badly fitted stroke is small).
constexpr double kMaxExcursion = 3.0;

// The rate_bank_v1 set: leaky integrals of the pan/tilt rate (rad) at these time constants, a
// learned higher-order linear filter from rate to lens beside the chain's own.
constexpr double kRateBankTimeConstantsS[] = {0.002, 0.005, 0.012, 0.03, 0.07, 0.17, 0.4, 1.0, 2.5};
constexpr int kRateBankSize = sizeof(kRateBankTimeConstantsS) / sizeof(double);

bool hasExcursionFeatures(const std::string& set) {
  return set == "excursion_v1" || set == "excursion_rate_v1";
}
bool hasRateBankFeatures(const std::string& set) {
  return set == "rate_bank_v1" || set == "excursion_rate_v1";
}

// Computes the named features of the chain's state (signal.features) and adds
// focal * nonlinear_residual * features to the lens (nothing when the residual is empty: the
// features alone, for its fit).
class LearnedResidualRunner final : public StabiliserStageRunner {
 public:
  LearnedResidualRunner(const LearnedResidualValues& p, const StabiliserModel& model,
                        const StabiliserRunContext& context)
      : residual_(p.nonlinear_residual),
        focal_px_(context.focal_px),
        stroke_px_(strokePx(model, context.focal_px)),
        size_(nonlinearFeatureCount(p.nonlinear_features)),
        excursion_(hasExcursionFeatures(p.nonlinear_features)) {
    using stage_numerics::leakDecay;
    using stage_numerics::leakWeight;
    if (excursion_) {
      for (double tau : kExcursionIntegralTimeConstantsS) {
        excursion_decay_.push_back(leakDecay(1.0 / tau, context.step_s));
        excursion_weight_.push_back(leakWeight(1.0 / tau, context.step_s));
      }
    }
    if (hasRateBankFeatures(p.nonlinear_features)) {
      for (double tau : kRateBankTimeConstantsS) {
        rate_bank_decay_.push_back(leakDecay(1.0 / tau, context.step_s));
        rate_bank_weight_.push_back(leakWeight(1.0 / tau, context.step_s));
      }
    }
  }
  void reset(StabiliserSignal& signal) override {
    excursion_state_.assign(excursion_decay_.size(), Eigen::Vector2d::Zero());
    rate_bank_state_.assign(rate_bank_decay_.size(), Eigen::Vector2d::Zero());
    signal.features = Eigen::VectorXd::Zero(size_);
  }
  void advance(StabiliserSignal& signal) override {
    Eigen::VectorXd& features = signal.features;
    int offset = 0;
    if (excursion_) {
      // excursion_v1, per axis i (other axis j), in focal-length units: u the unclipped command,
      // e = u / stroke (bounded), c the clipped command, a the actuator's output. With anti-windup
      // the angle never passes the stroke, so u is the limited command there.
      const Eigen::Vector2d u = signal.raw_command_px / focal_px_;
      const Eigen::Vector2d limit = stroke_px_ / focal_px_;
      const Eigen::Vector2d c = signal.command_px / focal_px_;
      const Eigen::Vector2d a = signal.actuator_px / focal_px_;
      Eigen::Vector2d e;
      for (int i = 0; i < 2; ++i) e(i) = std::clamp(u(i) / limit(i), -kMaxExcursion, kMaxExcursion);
      const Eigen::Vector2d pull = u.cwiseProduct(e.cwiseAbs2());
      for (std::size_t k = 0; k < excursion_state_.size(); ++k)
        excursion_state_[k] = excursion_decay_[k] * excursion_state_[k] +
                              excursion_weight_[k] / kExcursionIntegralTimeConstantsS[k] * pull;
      for (int i = 0; i < 2; ++i) {
        const int j = 1 - i;
        double* f = features.data() + i * kExcursionFeaturesPerAxis;
        f[0] = u(i);
        f[1] = limit(i) * std::tanh(e(i));
        f[2] = pull(i);
        f[3] = pull(i) * e(i) * e(i);
        f[4] = c(i);
        f[5] = a(i);
        f[6] = u(i) * e(j) * e(j);
        for (std::size_t k = 0; k < excursion_state_.size(); ++k) f[7 + k] = excursion_state_[k](i);
      }
      offset = 2 * kExcursionFeaturesPerAxis;
    }
    // rate_bank_v1: the leaky rate integrals (rad), x's then y's.
    const Eigen::Vector2d pan_tilt = signal.rate_rad_s.head<2>();
    for (std::size_t k = 0; k < rate_bank_state_.size(); ++k) {
      rate_bank_state_[k] = rate_bank_decay_[k] * rate_bank_state_[k] + rate_bank_weight_[k] * pan_tilt;
      features(offset + static_cast<long>(k)) = rate_bank_state_[k].x();
      features(offset + kRateBankSize + static_cast<long>(k)) = rate_bank_state_[k].y();
    }
    if (residual_.size() != 0) signal.lens_px += focal_px_ * (residual_ * features);
  }

 private:
  Eigen::MatrixXd residual_;
  double focal_px_;
  Eigen::Vector2d stroke_px_;
  long size_;
  bool excursion_;
  // Per time constant the leaky integral of the excursion-weighted command, and of the rate.
  std::vector<double> excursion_decay_, excursion_weight_, rate_bank_decay_, rate_bank_weight_;
  std::vector<Eigen::Vector2d> excursion_state_, rate_bank_state_;
};

}  // namespace

int nonlinearFeatureCount(const std::string& feature_set) {
  if (!hasExcursionFeatures(feature_set) && !hasRateBankFeatures(feature_set)) return 0;
  return (hasExcursionFeatures(feature_set) ? 2 * kExcursionFeaturesPerAxis : 0) +
         (hasRateBankFeatures(feature_set) ? 2 * kRateBankSize : 0);
}

const StabiliserStage& learnedResidualStage() {
  static const StabiliserStage stage{
      "learned_residual",
      "adds a linear map (2 x M) of a named set of M nonlinear features of the chain's state "
      "(excursion_v1, rate_bank_v1, excursion_rate_v1) to the lens (focal units)",
      false,
      true,
      {},
      {"nonlinear_features", "nonlinear_residual"},
      stage_numerics::make<LearnedResidualValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const LearnedResidualValues& p = valuesAs<LearnedResidualValues>(own);
        // Optional: files without it (every model before the learned nonlinear residual) still load.
        if (p.nonlinear_features.empty()) return;
        out << YAML::Key << "nonlinear_features" << YAML::Value << p.nonlinear_features;
        std::vector<double> nonlinear;
        for (long r = 0; r < p.nonlinear_residual.rows(); ++r)
          for (long c = 0; c < p.nonlinear_residual.cols(); ++c)
            nonlinear.push_back(p.nonlinear_residual(r, c));
        out << YAML::Key << "nonlinear_residual" << YAML::Value << YAML::Flow << nonlinear;
      },
      [](const YAML::Node& s, StageValues& own) {
        LearnedResidualValues* p = &valuesAs<LearnedResidualValues>(own);
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
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const LearnedResidualValues& p = valuesAs<LearnedResidualValues>(own);
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
      [](StageValues& own) {
        LearnedResidualValues* p = &valuesAs<LearnedResidualValues>(own);
        p->nonlinear_features.clear();
        p->nonlinear_residual.resize(0, 0);
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        const LearnedResidualValues& p = valuesAs<LearnedResidualValues>(own);
        return p.nonlinear_features.empty()
                   ? nullptr
                   : stage_numerics::runner<LearnedResidualRunner, LearnedResidualValues>(own, model, context);
      },
      [](const StageValues& own) {
        const LearnedResidualValues& p = valuesAs<LearnedResidualValues>(own);
        return p.nonlinear_features.empty() ? std::string()
                                            : "learned_residual:" + p.nonlinear_features;
      },
      nullptr};
  return stage;
}

}  // namespace deep_ois
