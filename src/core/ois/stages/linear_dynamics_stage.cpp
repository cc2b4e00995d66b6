// The linear-dynamics stage: a linear filter of free order from the three gyro axes to the raw
// command, raw command += focal * coefficients * (orthonormal basis state of the rate)
// (core/ois/linear_dynamics_basis.h). It stands in for what no mechanism names: a Kalman or
// alpha-beta intended-motion estimator, a velocity loop, a second-order centring, all linear
// filters of the gyro inside the stroke. Written before the stroke (and the actuator, when the
// model has one), so the stroke limits what it commands. Fitted in closed form (a ridge least
// squares) with the rest of the chain held: solveLinearDynamicsCoefficients below.
// With output_to_lens it adds to the lens after the last stage instead (past the stroke and the
// actuator), over a bank of first-order low-passes of the pan/tilt rate: the form into which the
// model file converts the residual banks of older files (stabiliser_model_file.cpp), exactly.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/linear_dynamics_rls.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "stabiliser_file_fields.h"
#include "stage_numerics.h"

namespace deep_ois {
namespace {

// Adds focal * coefficients * basis state to the raw command (the lens follows it at once until a
// stroke or an actuator after it acts), or to what the chain adds to the lens after its last stage.
class LinearDynamicsRunner final : public StabiliserStageRunner {
 public:
  LinearDynamicsRunner(const LinearDynamicsValues& p, const StabiliserModel&, const StabiliserRunContext& context)
      : basis_(p.basis, context.step_s),
        coefficients_(p.coefficients),
        focal_px_(context.focal_px),
        output_to_lens_(p.output_to_lens) {}
  void reset(StabiliserSignal&) override { basis_.reset(); }
  void advance(StabiliserSignal& signal) override {
    Eigen::Vector2d added;
    added.noalias() = coefficients_ * basis_.advance(signal.rate_rad_s);  // no allocation per step
    if (output_to_lens_) {
      signal.lens_added_px += focal_px_ * added;
      return;
    }
    signal.raw_command_px += focal_px_ * added;
    signal.command_px = signal.lens_px = signal.raw_command_px;
  }

 private:
  LinearDynamicsBasis basis_;
  Eigen::MatrixXd coefficients_;  // 2 x 3 order, focal units per basis state
  double focal_px_;
  bool output_to_lens_;
};

// The stage as a token's variant: "1hz_x8" (Laguerre, 1 Hz, 8 functions per axis), "1+10hz_x16"
// (two poles alternating); "lens_leaky_x5" for a bank of 5 first-order low-passes added to the lens
// (a converted file's: no refit starts it).
std::string basisVariant(const LinearDynamicsValues& values) {
  const LinearDynamicsBasisSpec& basis = values.basis;
  std::ostringstream variant;
  if (values.output_to_lens) variant << "lens_";
  if (basis.firstOrder()) {
    variant << "leaky_x" << basis.order;
    return variant.str();
  }
  variant << basis.pole_hz;
  if (basis.second_pole_hz > 0.0) variant << "+" << basis.second_pole_hz;
  variant << "hz_x" << basis.order;
  return variant.str();
}

LinearDynamicsBasisSpec basisOfVariant(const std::string& variant) {
  LinearDynamicsBasisSpec basis;
  if (variant.empty()) return basis;  // the default basis
  std::istringstream in(variant);
  char plus = 0;
  std::string rest;
  bool good = static_cast<bool>(in >> basis.pole_hz);
  if (good && in.peek() == '+') good = static_cast<bool>(in >> plus >> basis.second_pole_hz);
  good = good && static_cast<bool>(std::getline(in, rest));
  if (good && rest.rfind("hz_x", 0) == 0) {
    std::size_t used = 0;
    try {
      basis.order = std::stoi(rest.substr(4), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    good = used > 0 && 4 + used == rest.size();
  } else {
    good = false;
  }
  const std::string problem = good ? basis.validate(1e-3) : std::string("malformed");
  if (!problem.empty())
    throw std::invalid_argument("linear_dynamics: variant '" + variant + "' is not a basis such as "
                                "'1hz_x8' or '1+10hz_x16' (" + problem + ")");
  return basis;
}

}  // namespace

const StabiliserStage& linearDynamicsStage() {
  static const StabiliserStage stage{
      "linear_dynamics",
      "adds a linear filter of free order of the three gyro axes to the raw command (output: lens, "
      "to the lens after the chain): 2 x 3N coefficients (focal units) of a basis of N functions "
      "per axis, orthonormal (Laguerre) or first-order low-passes (time_constants_s)",
      true,
      {},
      {"linear_dynamics"},
      stage_numerics::make<LinearDynamicsValues>,
      [](YAML::Emitter& out, const StageValues& own) {
        const LinearDynamicsValues& p = valuesAs<LinearDynamicsValues>(own);
        const LinearDynamicsValues& v = p;
        if (!v.active()) return;  // optional: files without it load without the stage
        out << YAML::Key << "linear_dynamics" << YAML::Value << YAML::BeginMap;
        // Optional keys only when used (files of the raw-command Laguerre form keep their bytes).
        if (v.output_to_lens) out << YAML::Key << "output" << YAML::Value << "lens";
        if (v.basis.firstOrder()) {
          out << YAML::Key << "time_constants_s" << YAML::Value << YAML::Flow << v.basis.time_constants_s;
        } else {
          out << YAML::Key << "pole_hz" << YAML::Value << v.basis.pole_hz;
          out << YAML::Key << "second_pole_hz" << YAML::Value << v.basis.second_pole_hz;
          out << YAML::Key << "order" << YAML::Value << v.basis.order;
        }
        std::vector<double> coefficients;
        for (long r = 0; r < v.coefficients.rows(); ++r)
          for (long c = 0; c < v.coefficients.cols(); ++c) coefficients.push_back(v.coefficients(r, c));
        out << YAML::Key << "coefficients" << YAML::Value << YAML::Flow << coefficients;
        out << YAML::EndMap;
      },
      [](const YAML::Node& s, StageValues& own) {
        LinearDynamicsValues* p = &valuesAs<LinearDynamicsValues>(own);
        using stabiliser_file_fields::optional;
        using stabiliser_file_fields::required;
        *p = LinearDynamicsValues();
        if (!s["linear_dynamics"]) return true;
        const YAML::Node node = s["linear_dynamics"];
        LinearDynamicsValues& v = *p;
        const std::string output = optional<std::string>(node, "output", "raw_command");
        if (output != "raw_command" && output != "lens")
          throw StabiliserModelFileError("field 'linear_dynamics.output' must be raw_command or lens (got '" +
                                         output + "')");
        v.output_to_lens = output == "lens";
        if (node["time_constants_s"]) {
          v.basis.time_constants_s = required<std::vector<double>>(node, "time_constants_s");
          v.basis.order = static_cast<int>(v.basis.time_constants_s.size());
        } else {
          v.basis.pole_hz = required<double>(node, "pole_hz");
          v.basis.second_pole_hz = optional<double>(node, "second_pole_hz", 0.0);
          v.basis.order = required<int>(node, "order");
        }
        const auto coefficients = required<std::vector<double>>(node, "coefficients");
        const long n = 3L * std::max(0, v.basis.order);
        if (n == 0 || static_cast<long>(coefficients.size()) != 2 * n)
          throw StabiliserModelFileError("field 'linear_dynamics.coefficients' must have 2 x 3 x "
                                         "order values (row x, then row y)");
        v.coefficients.resize(2, n);
        for (long r = 0; r < 2; ++r)
          for (long c = 0; c < n; ++c) v.coefficients(r, c) = coefficients[static_cast<std::size_t>(r * n + c)];
        return true;
      },
      [](const StageValues& own, const StabiliserModel&) {
        const LinearDynamicsValues& p = valuesAs<LinearDynamicsValues>(own);
        const LinearDynamicsValues& v = p;
        if (!v.active()) return std::string();
        std::ostringstream why;
        // The predictor's step is at most 1 ms in every use: a pole the basis cannot run at 1 ms is
        // refused here, the rest by the runner at its own step.
        if (const std::string problem = v.basis.validate(1e-3); !problem.empty()) {
          why << "linear_dynamics: " << problem;
        } else if (v.coefficients.rows() != 2 || v.coefficients.cols() != 3 * v.basis.order ||
                   !v.coefficients.allFinite()) {
          why << "linear_dynamics.coefficients: must be a finite 2 x " << 3 * v.basis.order
              << " matrix (3 x order)";
        }
        return why.str();
      },
      [](const StageValues& own, const StabiliserModel& model, const StabiliserRunContext& context) {
        const LinearDynamicsValues& p = valuesAs<LinearDynamicsValues>(own);
        return p.active() ? stage_numerics::runner<LinearDynamicsRunner, LinearDynamicsValues>(own, model, context)
                                          : nullptr;
      },
      [](const StageValues& own) {
        const LinearDynamicsValues& p = valuesAs<LinearDynamicsValues>(own);
        return p.active() ? "linear_dynamics:" + basisVariant(p) : std::string();
      },
      // Started by a refit (refitStabiliserStages): the variant names the basis, the coefficients
      // start at zero (the refit's first step solves them in closed form).
      [](StageValues& own, const char* variant) {
        LinearDynamicsValues& p = valuesAs<LinearDynamicsValues>(own);
        if (!variant) {
          p = LinearDynamicsValues();
          return;
        }
        p.basis = basisOfVariant(variant);
        p.coefficients = Eigen::MatrixXd::Zero(2, 3 * p.basis.order);
      }};
  return stage;
}

namespace {

// The lens (px) at each observation's t_a and t_b for p over `recording` (NaN where the predictor
// does not cover them, or before the warm-up), fed as the fit feeds its predictor.
std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> lensAtObservations(
    const StabiliserModel& p, const StabiliserFitRecording& recording,
    const StabiliserFitOptions& options) {
  const Eigen::Vector2d nan = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> lens(recording.observations.size(),
                                                                {nan, nan});
  visitCoveredObservations(p, recording, options.step_s, options.warm_up_s,
                           [&](const LensShiftPredictor& predictor, std::size_t index) {
                             const LensMotionObservation& o = recording.observations[index];
                             lens[index] = {predictor.lensShiftAt(o.t_a_s), predictor.lensShiftAt(o.t_b_s)};
                           });
  return lens;
}

}  // namespace

LinearDynamicsEvidence linearDynamicsEvidence(const StabiliserModel& model,
                                              const std::vector<StabiliserFitRecording>& recordings,
                                              const StabiliserFitOptions& options) {
  const LinearDynamicsValues* own = model.find<LinearDynamicsValues>();
  if (!own || !own->active())
    throw std::invalid_argument("linearDynamicsEvidence: the model has no linear_dynamics "
                                "stage with coefficients (start it with its basis)");
  const Eigen::MatrixXd current = own->coefficients;
  const long n = current.cols();
  // The lens at each observation's ends for the current coefficients, and for each coefficient
  // column moved by a probe (both rows at once: each image axis answers its own row; a coupling
  // between the axes, a circular stroke, is left to the caller's acceptance test).
  auto lensOver = [&](const StabiliserModel& m) {
    std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> lens;
    for (const StabiliserFitRecording& recording : recordings) {
      const auto here = lensAtObservations(m, recording, options);
      lens.insert(lens.end(), here.begin(), here.end());
    }
    return lens;
  };
  const auto base = lensOver(model);
  std::vector<const LensMotionObservation*> observations;
  for (const StabiliserFitRecording& recording : recordings)
    for (const LensMotionObservation& o : recording.observations) observations.push_back(&o);
  const long m = static_cast<long>(observations.size());
  // Relative to the coefficients' scale (focal units per basis state: 1e-3 to 1), small enough that
  // the probe crosses the stroke's end stop on almost no sample.
  constexpr double kProbe = 1e-6;
  Eigen::MatrixXd along_x(m, n), along_y(m, n);
  StabiliserModel probe = model;
  for (long j = 0; j < n; ++j) {
    Eigen::MatrixXd& probed = probe.get<LinearDynamicsValues>().coefficients;
    probed = current;
    probed.col(j).array() += kProbe;
    const auto lens = lensOver(probe);
    for (long i = 0; i < m; ++i) {
      const std::size_t k = static_cast<std::size_t>(i);
      const Eigen::Vector2d moved = (lens[k].second - lens[k].first) - (base[k].second - base[k].first);
      along_x(i, j) = moved.x() / kProbe;
      along_y(i, j) = moved.y() / kProbe;
    }
  }
  // The usable rows: the linearised lens motion, motion - lens(C) + J C = J C'.
  std::vector<long> rows;
  for (long i = 0; i < m; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const Eigen::Vector2d predicted = base[k].second - base[k].first;
    if (predicted.allFinite() && along_x.row(i).allFinite() && along_y.row(i).allFinite()) rows.push_back(i);
  }
  const long used = static_cast<long>(rows.size());
  LinearDynamicsEvidence evidence;
  evidence.along_x.resize(used, n);
  evidence.along_y.resize(used, n);
  evidence.targets.resize(used, 2);
  evidence.weights.resize(used);
  evidence.residual_px.resize(used);
  evidence.stamps_s.resize(used);
  for (long r = 0; r < used; ++r) {
    const long i = rows[static_cast<std::size_t>(r)];
    const std::size_t k = static_cast<std::size_t>(i);
    const LensMotionObservation& o = *observations[k];
    const Eigen::Vector2d residual = o.motion_px - (base[k].second - base[k].first);
    evidence.along_x.row(r) = along_x.row(i);
    evidence.along_y.row(r) = along_y.row(i);
    evidence.targets(r, 0) = residual.x() + along_x.row(i).dot(current.row(0));
    evidence.targets(r, 1) = residual.y() + along_y.row(i).dot(current.row(1));
    evidence.weights(r) = std::max(0.0, o.weight);
    evidence.residual_px(r) = residual.norm();
    evidence.stamps_s(r) = o.t_b_s;
  }
  return evidence;
}

StabiliserModel solveLinearDynamicsCoefficients(const StabiliserModel& model,
                                                const std::vector<StabiliserFitRecording>& recordings,
                                                const StabiliserFitOptions& options, double ridge) {
  if (!model.find<LinearDynamicsValues>() || !model.find<LinearDynamicsValues>()->active())
    throw std::invalid_argument("solveLinearDynamicsCoefficients: the model has no linear_dynamics "
                                "stage with coefficients (start it with its basis)");
  const LinearDynamicsEvidence evidence = linearDynamicsEvidence(model, recordings, options);
  const long n = evidence.along_x.cols();
  // Per image axis: its row of coefficients by the package's robust ridge regression on the
  // linearised lens motion, Huber-weighted by the current residual.
  RobustRidgeRegression per_axis[2] = {RobustRidgeRegression(n, 1, RobustLoss::huber(options.huber_px)),
                                       RobustRidgeRegression(n, 1, RobustLoss::huber(options.huber_px))};
  for (long r = 0; r < evidence.rows(); ++r)
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::RowVectorXd features = axis == 0 ? evidence.along_x.row(r) : evidence.along_y.row(r);
      per_axis[axis].add(features.transpose(), Eigen::VectorXd::Constant(1, evidence.targets(r, axis)),
                         evidence.weights(r), evidence.residual_px(r));
    }
  if (per_axis[0].count() < static_cast<std::size_t>(n))
    throw std::invalid_argument("solveLinearDynamicsCoefficients: fewer usable lens motions than coefficients");
  StabiliserModel solved = model;
  Eigen::MatrixXd& coefficients = solved.get<LinearDynamicsValues>().coefficients;
  for (int axis = 0; axis < 2; ++axis) {
    Eigen::MatrixXd row;  // n x 1
    if (!per_axis[axis].solve(ridge, &row)) return model;
    coefficients.row(axis) = row.col(0).transpose();
  }
  return solved;
}

}  // namespace deep_ois
