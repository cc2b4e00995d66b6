#include "deep_ois/core/ois/stabiliser_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iomanip>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The parameters a refinement frees: the fitted parameters (core/ois/stabiliser_stage.h), named
// and bounded there, of the stages being fitted, in the stages' order: the chain's (centring,
// stroke, actuator) always, and those named (stage names or tokens: "pan_detection",
// "excursion_centring", "actuator_coupling"); with `model`, only the stages it has (a composition
// without the centring, around a linear-dynamics stage). Entry j reads and writes its parameter on
// the stage's own values in a model; a write is held in the parameter's bounds (a parameter that
// ends on one is reported by reviewStabiliserFit).
class FreeParameters {
 public:
  explicit FreeParameters(std::vector<std::string> stages = {}, const StabiliserModel* model = nullptr) {
    for (std::string& stage : stages) stage = stageOfToken(stage);
    for (const char* chain : {"centring", "stroke", "actuator"}) stages.push_back(chain);
    for (const StabiliserStage& stage : stabiliserStages()) {
      if (std::find(stages.begin(), stages.end(), stage.name) == stages.end()) continue;
      if (model && !model->has(stage.name)) continue;
      for (const FittedStabiliserParameter& parameter : stage.fitted)
        entries_.push_back({stage.name, &parameter});
    }
  }
  int size() const { return static_cast<int>(entries_.size()); }
  // Entry j's parameter: name, bounds, coordinate and difference step.
  const FittedStabiliserParameter& parameter(int j) const {
    return *entries_[static_cast<std::size_t>(j)].parameter;
  }

  // Entry j's value in p (in its parameter's unit, not the solver's coordinate).
  double value(int j, const StabiliserModel& p) const {
    const Entry& entry = entries_[static_cast<std::size_t>(j)];
    return entry.parameter->value(*p.values(entry.stage));
  }
  // Sets entry j's value in p, held in its bounds.
  void set(int j, double value, StabiliserModel* p) const {
    const Entry& entry = entries_[static_cast<std::size_t>(j)];
    const FittedStabiliserParameter& parameter = *entry.parameter;
    parameter.set(*p->values(entry.stage), std::clamp(value, parameter.lower, parameter.upper));
  }

 private:
  // The fitted parameters of the stages being fitted, with their stage (whose values they are).
  struct Entry {
    const char* stage;
    const FittedStabiliserParameter* parameter;
  };
  std::vector<Entry> entries_;
};

// Every usable observation's weighted residual (predicted - observed motion, 2 per observation).
struct Residuals {
  Eigen::VectorXd values;              // 2 per observation, weighted by sqrt(weight)
  std::vector<double> sqrt_weights;    // per observation (data weight only)
  std::size_t used = 0, skipped = 0;
};

Residuals residualsOf(const StabiliserModel& parameters,
                      const std::vector<StabiliserFitRecording>& recordings,
                      const StabiliserFitOptions& options) {
  std::vector<double> values;
  Residuals result;
  for (const StabiliserFitRecording& recording : recordings) {
    std::size_t used_here = 0;
    visitCoveredObservations(parameters, recording, options.step_s, options.warm_up_s,
            [&](const LensShiftPredictor& predictor, std::size_t index) {
              const LensMotionObservation& o = recording.observations[index];
              const Eigen::Vector2d r =
                  predictor.lensShiftAt(o.t_b_s) - predictor.lensShiftAt(o.t_a_s) - o.motion_px;
              const double w = std::sqrt(std::max(0.0, o.weight));
              values.push_back(w * r.x());
              values.push_back(w * r.y());
              result.sqrt_weights.push_back(w);
              ++used_here;
            });
    result.used += used_here;
    result.skipped += recording.observations.size() - used_here;
  }
  result.values = Eigen::Map<Eigen::VectorXd>(values.data(), static_cast<long>(values.size()));
  return result;
}

double weightedRms(const Eigen::VectorXd& residuals, const Eigen::VectorXd& weights) {
  if (residuals.size() == 0) return kNaN;
  return std::sqrt(2.0 * residuals.cwiseAbs2().cwiseProduct(weights).sum() / weights.sum());
}

// The fit's robust cost, the solver's convention (core/common/nonlinear_least_squares.h): 1/2 sum
// of Huber(|weighted residual|^2) over the observations.
double huberCost(const Eigen::VectorXd& residuals, double huber_px) {
  const RobustLoss loss = RobustLoss::huber(huber_px);
  double cost = 0.0;
  for (long k = 0; k + 1 < residuals.size(); k += 2) cost += 0.5 * loss.rho(residuals.segment<2>(k).squaredNorm());
  return cost;
}

// The refinement: the free parameters' values fitted by the package's solver
// (core/common/nonlinear_least_squares.h), Huber loss per observation, bounds and logarithmic
// coordinates as the stages declare them, forward differences for the Jacobian.
// `rms_history`, when given, gets the RMS residual (pixels) after every accepted step.
StabiliserModel levenbergMarquardt(StabiliserModel start, const FreeParameters& packing,
                                        const std::vector<StabiliserFitRecording>& recordings,
                                        const StabiliserFitOptions& options, int iterations,
                                        double* final_cost, std::vector<double>* rms_history = nullptr) {
  NonlinearLeastSquaresProblem problem;
  Eigen::VectorXd values(packing.size());
  for (int j = 0; j < packing.size(); ++j) {
    const FittedStabiliserParameter& p = packing.parameter(j);
    problem.parameters.push_back({p.name, p.lower, p.upper, p.logarithmic, p.fit_step});
    values(j) = std::clamp(packing.value(j, start), p.lower, p.upper);
  }
  auto unpack = [&](const Eigen::VectorXd& v) {
    StabiliserModel p = start;
    for (int j = 0; j < packing.size(); ++j) packing.set(j, v(j), &p);
    return p;
  };
  problem.block_size = 2;  // an observation's x and y share its Huber weight
  problem.residuals = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) {
    *r = residualsOf(unpack(v), recordings, options).values;  // a changed coverage is refused
    return true;
  };
  NonlinearLeastSquaresOptions solver;
  solver.loss = RobustLoss::huber(options.huber_px);
  solver.engine = options.solver_engine;
  solver.max_iterations = iterations;
  solver.function_tolerance = 1e-6;
  const NonlinearLeastSquaresReport report = solveNonlinearLeastSquares(problem, values, solver);
  if (rms_history) rms_history->insert(rms_history->end(), report.rms_history.begin(), report.rms_history.end());
  if (!report.usable()) {
    if (final_cost) *final_cost = stabiliserFitCost(start, recordings, options);
    return start;
  }
  if (final_cost) *final_cost = report.final_cost;  // the solver's cost is huberCost's
  return unpack(report.values);
}

// Step 2 of a composition with the linear-dynamics stage (refitStabiliserStages): block coordinate
// descent from `model` (its coefficients from step 1). Each round the solver moves the other
// stages' parameters (`packing`) with the coefficients held, then the coefficients are solved
// again in closed form with the rest held; a block's step is kept only when it lowers the Huber
// cost, and the rounds stop when one lowers it by less than 0.1 %.
//
// Why not the coefficients as solver parameters: 2 x 3N of them (96 for 16 functions per axis)
// would cost a run of the chain each per Jacobian, where the closed form costs one run per column
// for both rows, and the cost is quadratic in them inside the stroke: the closed form is their
// exact minimiser there, the solver would take several iterations to reach it.
StabiliserModel refitWithLinearDynamics(StabiliserModel model, const FreeParameters& packing,
                                        const std::vector<StabiliserFitRecording>& recordings,
                                        const StabiliserFitOptions& options, double* final_cost,
                                        std::vector<double>* rms_history) {
  constexpr int kRounds = 3;
  double cost = stabiliserFitCost(model, recordings, options);
  const int iterations = std::max(1, options.iterations / kRounds);
  for (int round = 0; round < kRounds; ++round) {
    const double round_start = cost;
    double moved_cost = 0.0;
    StabiliserModel moved = levenbergMarquardt(model, packing, recordings, options, iterations, &moved_cost, rms_history);
    if (moved_cost < cost) model = std::move(moved), cost = moved_cost;
    StabiliserModel solved = solveLinearDynamicsCoefficients(model, recordings, options);
    const double solved_cost = stabiliserFitCost(solved, recordings, options);
    if (solved_cost < cost) model = std::move(solved), cost = solved_cost;
    if (!(cost < (1.0 - 1e-3) * round_start)) break;
  }
  *final_cost = cost;
  return model;
}

// `refined` as the fit's result: parameters, observation counts and its RMS.
void keepRefined(const StabiliserModel& refined, const std::vector<StabiliserFitRecording>& recordings,
                 const StabiliserFitOptions& options, StabiliserFitResult* result) {
  const Residuals residuals = residualsOf(refined, recordings, options);
  result->parameters = refined;
  result->observations_used = residuals.used;
  result->observations_skipped = residuals.skipped;
  result->rms_px = weightedRms(residuals.values, Eigen::VectorXd::Ones(residuals.values.size()));
}

// A stabiliser cancels (about) the rotation: the gain's largest singular value is near 1 (0.8-1.1
// on the simulator's modules, 0.97 for the generic model), whatever the axes' mapping and sign.
constexpr double kMostGain = 1.5, kLeastGain = 0.3;

// The recordings with every observation moved by shift_s + readout_change_s * (readout_fraction -
// 0.5): a frame moved in time at its middle row, and its readout stretched about it.
std::vector<StabiliserFitRecording> movedInTime(
    const std::vector<StabiliserFitRecording>& recordings, double shift_s,
    double readout_change_s) {
  std::vector<StabiliserFitRecording> moved = recordings;
  for (StabiliserFitRecording& recording : moved) {
    for (LensMotionObservation& o : recording.observations) {
      const double dt = shift_s + readout_change_s * (o.readout_fraction - 0.5);
      o.t_a_s += dt;
      o.t_b_s += dt;
    }
  }
  return moved;
}

// The strokes a fit scans per axis before the solver moves them (degrees): the cost has no slope in
// a limit the lens never reaches, so the solver alone cannot find a stroke far from its start.
const std::vector<double>& strokeScanDeg() {
  static const std::vector<double> strokes = {0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.3, 1.7, 2.3, 3.0, 5.0};
  return strokes;
}

// The timing check scans +-this, milliseconds (a grid of 2 ms steps, refined between them).
constexpr double kTimingScanMs = 20.0;

// The timing check of the review: see StabiliserFitReview::best_lens_lag_ms.
void checkTiming(const StabiliserModel& physical,
                 const std::vector<StabiliserFitRecording>& recordings,
                 const StabiliserFitOptions& options, StabiliserFitReview* review) {
  // A lens that hardly follows the rotation (OIS off) has no timing to check: its fit is noise.
  const Eigen::Matrix2d& chain_gain = physical.get<CentringValues>().gain;
  if (Eigen::JacobiSVD<Eigen::Matrix2d>(chain_gain).singularValues()(0) < kLeastGain) return;
  StabiliserModel without_lag = physical;
  without_lag.get<ActuatorValues>().sensor_lag_s = 0.0;
  // Mean Huber cost per observation used (the coverage changes a little with the shift).
  auto cost = [&](double shift_s, double readout_change_s) {
    const Residuals r =
        residualsOf(without_lag, movedInTime(recordings, shift_s, readout_change_s), options);
    return r.used > 0 ? huberCost(r.values, options.huber_px) / static_cast<double>(r.used)
                      : std::numeric_limits<double>::infinity();
  };
  // The best of a grid, refined by a parabola through the best point and its neighbours.
  auto scan = [&](const std::function<double(double)>& f, double step, int half_count) {
    std::vector<double> x, y;
    for (int k = -half_count; k <= half_count; ++k) {
      x.push_back(k * step);
      y.push_back(f(k * step));
    }
    const std::size_t best =
        static_cast<std::size_t>(std::min_element(y.begin(), y.end()) - y.begin());
    double at = x[best];
    if (best > 0 && best + 1 < x.size()) {
      const double curvature = y[best - 1] - 2.0 * y[best] + y[best + 1];
      if (curvature > 0.0) at += 0.5 * step * (y[best - 1] - y[best + 1]) / curvature;
    }
    return at;
  };
  constexpr double kStepS = 0.002;
  constexpr int kHalfCount = 10;  // +-20 ms: kTimingScanMs
  double shift = scan([&](double s) { return cost(s, 0.0); }, kStepS, kHalfCount);
  const double readout_change = scan([&](double r) { return cost(shift, r); }, kStepS, kHalfCount);
  shift = scan([&](double s) { return cost(s, readout_change); }, kStepS, kHalfCount);
  // Observations fitted at earlier times (a negative shift) are a lens that lags the gyro.
  review->best_lens_lag_ms = -1000.0 * shift;
  review->best_readout_change_ms = 1000.0 * readout_change;

  // A module's position loop lags its gyro by 0-3 ms (the simulator's noisiest Hall sensor: 3 ms);
  // it never leads. A readout change is suspect when it is large against the readout and it pays.
  constexpr double kMostLagMs = 4.0, kMostLeadMs = 1.0;
  const double cost_without_change = cost(shift, 0.0);
  const double gain =
      cost_without_change > 0.0 ? cost(shift, readout_change) / cost_without_change : 1.0;
  const double readout_ms = 1000.0 * options.readout_time_s;
  const double change_ms = 1000.0 * readout_change;
  std::ostringstream line;
  line.setf(std::ios::fixed);
  line.precision(1);
  if (std::abs(change_ms) > std::max(2.0, 0.15 * readout_ms) && gain < 0.98) {
    line << "readout_time: the lens motion fits best with the rows " << std::abs(change_ms)
         << " ms " << (change_ms > 0.0 ? "further apart" : "closer together")
         << " than the gyro config places them";
    if (readout_ms > 0.0)
      line << " (a readout of " << readout_ms + change_ms << " ms, the config says " << readout_ms
           << " ms)";
    line << ": the readout time looks wrong; take it from the camera (its data sheet or its "
            "recorded readout) and train again";
    review->timing.push_back(line.str());
    line.str("");
  }
  const double lag_ms = review->best_lens_lag_ms;
  if (lag_ms < -kMostLeadMs || lag_ms > kMostLagMs) {
    const bool log = options.target == LensMotionTarget::kLensLog;
    line << (log ? "lens_shift_time_offset" : "time_offset") << ": the lens motion fits best "
         << std::abs(lag_ms) << " ms " << (lag_ms > 0.0 ? "behind" : "ahead of")
         << " the gyro at the times the gyro config gives ("
         << (lag_ms > 0.0 ? "a module's own sensor lag is 0-3 ms"
                          : "a stabiliser never moves before its gyro")
         << "): ";
    if (log) {
      // A lens log has no images to calibrate against: its own clock is what moves.
      line << "the lens log's clock looks off by about " << std::abs(lag_ms) << " ms"
           << (lag_ms > 0.0 ? " less the module's own lag" : "")
           << "; add " << std::showpos << std::setprecision(4) << -1e-3 * lag_ms
           << std::noshowpos << std::setprecision(1)
           << " s to lens_shift_time_offset in the gyro config (camera time = logged stamp + "
              "lens_shift_time_offset), or let train_stabiliser --fit-time-offset apply it";
    } else {
      line << "the camera-IMU time offset (or the readout) looks wrong by about "
           << std::abs(lag_ms) << " ms" << (lag_ms > 0.0 ? " less the module's own lag" : "")
           << "; run calibrate on the recordings";
    }
    review->timing.push_back(line.str());
  }
}

}  // namespace

std::string StabiliserFitOptions::validate() const {
  std::ostringstream why;
  if (!(huber_px > 0.0)) why << "huber_px: must be positive";
  else if (iterations < 1) why << "iterations: must be >= 1";
  else if (!(step_s > 0.0 && step_s <= 0.01)) why << "step_s: must be in (0, 0.01] s";
  else if (!(warm_up_s >= 0.0)) why << "warm_up_s: must be >= 0";
  else if (!(readout_time_s >= 0.0))
    why << "readout_time_s: must be >= 0";
  else {
    for (double rate : pan_thresholds_rad_s)
      if (!(rate >= 0.0)) return "pan_thresholds_rad_s: must be >= 0 (0 = off)";
  }
  return why.str();
}

LensMotionTarget lensMotionTargetNamed(const std::string& name) {
  if (name == "images") return LensMotionTarget::kImages;
  if (name == "log") return LensMotionTarget::kLensLog;
  if (name == "truth") return LensMotionTarget::kSimulatorTruth;
  throw std::invalid_argument("lens motion target '" + name + "': expected images, log or truth");
}

const char* lensMotionTargetName(LensMotionTarget target) {
  switch (target) {
    case LensMotionTarget::kImages:
      return "images";
    case LensMotionTarget::kLensLog:
      return "log";
    case LensMotionTarget::kSimulatorTruth:
      return "truth";
  }
  return "images";
}

std::string timingCheckSummary(const StabiliserFitReview& review) {
  if (!std::isfinite(review.best_lens_lag_ms)) return "timing check: not run";
  // A best value on the end of the scan is no optimum: the cost kept falling beyond it.
  auto value = [](double ms) {
    std::ostringstream out;
    out.setf(std::ios::fixed);
    out.precision(1);
    out << ms << " ms";
    if (std::abs(ms) >= kTimingScanMs - 1e-6)
      out << " (the end of the +-" << kTimingScanMs << " ms scanned: no optimum inside it)";
    return out.str();
  };
  const double lag = review.best_lens_lag_ms;
  std::string line = "timing check: the lens motion fits best " + value(std::abs(lag)) + " " +
                     (lag >= 0.0 ? "behind" : "ahead of") + " the gyro, with the readout changed by " +
                     value(review.best_readout_change_ms);
  return line;
}

bool StabiliserFitReview::onBound(const std::string& parameter) const {
  return std::find(on_bound_parameters.begin(), on_bound_parameters.end(), parameter) !=
         on_bound_parameters.end();
}

StabiliserFitReview reviewStabiliserFit(const StabiliserModel& p, LensMotionTarget target) {
  StabiliserFitReview review;
  // What can put the lens motions on the wrong scale or time, for their source: the images carry
  // the camera-IMU calibration's errors, a lens log its convention and clock, the simulator's truth
  // neither (only the camera_info's focal length can disagree with it).
  const char* scale_causes =
      target == LensMotionTarget::kLensLog
          ? "the lens motions are likely on the wrong scale (a lens log in other units than the "
            "image's pixels: set lens_shift_scale in the gyro config, e.g. image width / active "
            "array width) or the focal length (camera_info) is wrong"
      : target == LensMotionTarget::kImages
          ? "the images' lens motions likely hold calibration errors the lens absorbed (a wrong "
            "time_offset, readout_time or IMU -> camera rotation: run calibrate on the recordings) "
            "or the focal length (camera_info) is wrong"
          : "the focal length (camera_info) likely differs from the simulated camera's";
  const char* early_frames =
      target == LensMotionTarget::kLensLog
          ? "a module without sensor lag, or a lens log whose clock leads the gyro: see "
            "lens_shift_time_offset (camera time = logged stamp + it)"
          : "a module without sensor lag, or frames placed too early in IMU time by a time offset "
            "or readout error; if unsure, run calibrate";
  // Every fitted parameter of the stages (stabiliser_stage.h) the model uses, against the bounds
  // the fit keeps it in.
  for (const StageInstance& instance : p.stages()) {
    for (const FittedStabiliserParameter& parameter : instance.stage->fitted) {
      if (parameter.used && !parameter.used(*instance.values)) continue;
      if (!std::isfinite(parameter.lower) || !std::isfinite(parameter.upper)) continue;
      const double value = parameter.value(*instance.values);
      const double tolerance = 1e-6 * std::max(1.0, std::abs(parameter.upper));
      const bool lower = value <= parameter.lower + tolerance;
      if (!lower && value < parameter.upper - tolerance) continue;
      std::ostringstream line;
      line << parameter.what << " " << value << (parameter.unit[0] ? " " : "") << parameter.unit
           << " is the fit's " << (lower ? "lower" : "upper") << " bound: the data wanted "
           << (lower ? "less" : "more");
      // No stabiliser moves before its gyro: frames placed too early in IMU time look like that.
      if (lower && std::string(parameter.name) == "sensor_lag_s")
        line << " (the lens moves with its gyro, no later: " << early_frames << ")";
      review.on_bound.push_back(line.str());
      review.on_bound_parameters.push_back(parameter.name);
    }
  }

  constexpr double kMostStrokeDeg = 3.0;  // modules travel about +-0.5 to +-1.5 deg
  // The plausibility of the centring's gain and the stroke, when the model has them.
  const CentringValues* centring = p.find<CentringValues>();
  const StrokeValues* stroke_values = p.find<StrokeValues>();
  if (!centring || !stroke_values) return review;
  const Eigen::Matrix2d& g = centring->gain;
  const Eigen::Vector2d singular = Eigen::JacobiSVD<Eigen::Matrix2d>(g).singularValues();
  std::ostringstream gain;
  gain.precision(3);
  gain << "gain [" << g(0, 0) << " " << g(0, 1) << "; " << g(1, 0) << " " << g(1, 1)
       << "] (it cancels " << 100.0 * singular(0) << " % of the rotation)";
  if (singular(0) > kMostGain) {
    review.implausible.push_back(gain.str() +
                                 ": a stabiliser cancels about the rotation (gain near 1), not "
                                 "more; " +
                                 scale_causes);
  } else if (singular(0) < kLeastGain) {
    review.implausible.push_back(
        gain.str() + ": the lens hardly follows the rotation; the OIS was likely off (then the "
        "camera needs no lens model)" +
        (target == LensMotionTarget::kLensLog
             ? std::string(" or the lens motions are on the wrong scale (lens_shift_scale)")
             : std::string()));
  }
  const double stroke = std::max(stroke_values->stroke_x_deg, stroke_values->stroke_y_deg);
  if (stroke > kMostStrokeDeg) {
    std::ostringstream line;
    line.precision(3);
    line << "stroke " << stroke_values->stroke_x_deg << " x " << stroke_values->stroke_y_deg
         << " deg: beyond what a module's lens travels (about 0.5-1.5 deg); " << scale_causes;
    review.implausible.push_back(line.str());
  }
  return review;
}

void visitCoveredObservations(const StabiliserModel& parameters, const StabiliserFitRecording& recording,
                              double step_s, double warm_up_s,
                              const std::function<void(const LensShiftPredictor&, std::size_t)>& visit,
                              const std::function<void(LensShiftPredictor&)>& prepare) {
  if (recording.rates.empty() || recording.observations.empty()) return;
  double span = 0.0;
  for (const LensMotionObservation& o : recording.observations) span = std::max(span, o.t_b_s - o.t_a_s);
  LensShiftPredictor predictor(parameters, recording.focal_px, step_s, std::max(0.25, 2.0 * span));
  predictor.max_gap_s = std::numeric_limits<double>::infinity();  // the recording's own gaps: fed
  if (prepare) prepare(predictor);
  // The observations by t_b: the order in which the predictor can answer them.
  std::vector<std::size_t> order(recording.observations.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return recording.observations[a].t_b_s < recording.observations[b].t_b_s;
  });
  const double usable_from = recording.rates.front().stamp_s + warm_up_s;
  std::size_t next_rate = 0;
  for (std::size_t index : order) {
    const LensMotionObservation& o = recording.observations[index];
    while (next_rate < recording.rates.size() && (!predictor.started() || predictor.newestStamp() < o.t_b_s))
      predictor.addRate(recording.rates[next_rate++]);
    if (o.t_a_s < usable_from || !predictor.covers(o.t_a_s) || !predictor.covers(o.t_b_s)) continue;
    visit(predictor, index);
  }
}

std::vector<Eigen::Vector2d> predictLensMotion(const StabiliserModel& parameters,
                                               const StabiliserFitRecording& recording,
                                               double step_s, double warm_up_s) {
  std::vector<Eigen::Vector2d> predicted(recording.observations.size(),
                                         Eigen::Vector2d::Constant(kNaN));
  visitCoveredObservations(parameters, recording, step_s, warm_up_s,
          [&](const LensShiftPredictor& predictor, std::size_t index) {
            const LensMotionObservation& o = recording.observations[index];
            predicted[index] = predictor.lensShiftAt(o.t_b_s) - predictor.lensShiftAt(o.t_a_s);
          });
  return predicted;
}

double stabiliserFitCost(const StabiliserModel& parameters,
                         const std::vector<StabiliserFitRecording>& recordings,
                         const StabiliserFitOptions& options) {
  return huberCost(residualsOf(parameters, recordings, options).values, options.huber_px);
}

StabiliserScore scoreStabiliser(const StabiliserModel& parameters,
                                const std::vector<StabiliserFitRecording>& recordings,
                                const StabiliserFitOptions& options) {
  double sum = 0.0, sum_without = 0.0, weights = 0.0;
  StabiliserScore score;
  for (const StabiliserFitRecording& recording : recordings) {
    const auto predicted =
        predictLensMotion(parameters, recording, options.step_s, options.warm_up_s);
    for (std::size_t k = 0; k < predicted.size(); ++k) {
      if (!predicted[k].allFinite()) continue;
      const LensMotionObservation& o = recording.observations[k];
      sum += o.weight * (predicted[k] - o.motion_px).squaredNorm();
      sum_without += o.weight * o.motion_px.squaredNorm();
      weights += o.weight;
      ++score.observations;
    }
  }
  if (weights > 0.0) {
    score.rms_px = std::sqrt(sum / weights);
    score.rms_without_model_px = std::sqrt(sum_without / weights);
  }
  return score;
}

StabiliserModel noLensMotion() {
  StabiliserModel p = StabiliserModel();
  p.get<CentringValues>().gain.setZero();
  p.get<PanDetectionValues>().pan_detection_rate_rad_s = 0.0;
  return p;
}

StabiliserFitResult fitStabiliser(const std::vector<StabiliserFitRecording>& recordings,
                                  const StabiliserFitOptions& options,
                                  const ProgressCallback& progress) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("fitStabiliser: " + problem);
  for (const StabiliserFitRecording& recording : recordings) {
    if (!(recording.focal_px > 0.0))
      throw std::invalid_argument("fitStabiliser: " + recording.name + ": focal_px must be positive");
    for (std::size_t k = 1; k < recording.rates.size(); ++k) {
      if (!(recording.rates[k].stamp_s > recording.rates[k - 1].stamp_s))
        throw std::invalid_argument("fitStabiliser: " + recording.name +
                                    ": gyro stamps must increase (sample " + std::to_string(k) + ")");
    }
  }
  StabiliserFitResult result;
  StabiliserFitOptions physical_options = options;
  auto log = [&](const std::string& line) { result.log.push_back(line); };

  // Start: the ideal stabiliser's structure with its sign and scale from a linear fit of the
  // gain at a few centring corners (the only linear part), then refine everything.
  StabiliserModel start;
  // No saturation until the fit finds it.
  start.get<StrokeValues>().stroke_x_deg = start.get<StrokeValues>().stroke_y_deg = 5.0;
  start.get<ActuatorValues>().actuator_natural_hz = 40.0;
  const std::vector<double> corners_hz = {0.1, 0.3, 0.6, 1.2, 2.5};
  const std::size_t total_steps = corners_hz.size() + 3 +
                                  options.pan_thresholds_rad_s.size() *
                                      (options.try_circular_stroke ? 2 : 1);
  std::size_t done = 0;
  auto tick = [&] {
    if (progress) progress(++done, total_steps);
  };
  double best_cost = std::numeric_limits<double>::infinity();
  StabiliserModel best = start;
  for (double corner : corners_hz) {
    StabiliserModel candidate = start;
    candidate.get<CentringValues>().highpass_corner_hz = corner;
    // Linear least squares for the gain: the lens motion is linear in it (no stroke reached).
    Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
    Eigen::Vector4d b = Eigen::Vector4d::Zero();
    std::vector<std::vector<Eigen::Vector2d>> unit_responses(4);
    for (int entry = 0; entry < 4; ++entry) {
      StabiliserModel unit = candidate;
      unit.get<CentringValues>().gain.setZero();
      unit.get<CentringValues>().gain(entry / 2, entry % 2) = 1.0;
      for (const StabiliserFitRecording& recording : recordings) {
        const auto predicted = predictLensMotion(unit, recording, options.step_s, options.warm_up_s);
        unit_responses[static_cast<std::size_t>(entry)].insert(
            unit_responses[static_cast<std::size_t>(entry)].end(), predicted.begin(),
            predicted.end());
      }
    }
    std::size_t k = 0;
    for (const StabiliserFitRecording& recording : recordings) {
      for (const LensMotionObservation& o : recording.observations) {
        Eigen::Matrix<double, 2, 4> M;
        for (int entry = 0; entry < 4; ++entry)
          M.col(entry) = unit_responses[static_cast<std::size_t>(entry)][k];
        ++k;
        if (!M.allFinite()) continue;
        A += o.weight * M.transpose() * M;
        b += o.weight * M.transpose() * o.motion_px;
      }
    }
    const Eigen::Vector4d g = A.ldlt().solve(b);
    if (g.allFinite()) candidate.get<CentringValues>().gain << g(0), g(1), g(2), g(3);
    const Residuals residuals = residualsOf(candidate, recordings, physical_options);
    const double cost = huberCost(residuals.values, options.huber_px);
    std::ostringstream line;
    line << "start: corner " << corner << " Hz, gain [" << g.transpose() << "], cost " << cost;
    log(line.str());
    if (cost < best_cost) {
      best_cost = cost;
      best = candidate;
    }
    tick();
  }
  const Residuals initial = residualsOf(best, recordings, physical_options);
  if (initial.used == 0) {
    throw std::invalid_argument(
        "fitStabiliser: no usable observation (each must lie inside its recording's gyro stream, "
        "after the first " + std::to_string(options.warm_up_s) + " s)");
  }

  // A first refinement with the stroke out of reach (the gain and corner it settles need no
  // stroke), then the stroke: the cost has no slope in a limit the model never reaches, so scan
  // it per axis (a cost evaluation each) and let the full refinement below move it.
  {
    double cost = 0.0;
    best = levenbergMarquardt(best, FreeParameters(), recordings, physical_options,
                              std::max(1, options.iterations / 3), &cost, &result.rms_history);
    std::ostringstream line;
    line << "first refinement: corner " << best.get<CentringValues>().highpass_corner_hz
         << " Hz, cost " << cost;
    log(line.str());
  }
  for (int axis = 0; axis < 2; ++axis) {
    double axis_best = std::numeric_limits<double>::infinity();
    StabiliserModel scanned = best;
    for (double stroke : strokeScanDeg()) {
      StabiliserModel candidate = best;
      StrokeValues& limits = candidate.get<StrokeValues>();
      (axis == 0 ? limits.stroke_x_deg : limits.stroke_y_deg) = stroke;
      const double cost =
          stabiliserFitCost(candidate, recordings, physical_options);
      if (cost < axis_best) {
        axis_best = cost;
        scanned = candidate;
      }
    }
    best = scanned;
    std::ostringstream line;
    line << "stroke scan: " << (axis == 0 ? "x " : "y ")
         << (axis == 0 ? best.get<StrokeValues>().stroke_x_deg : best.get<StrokeValues>().stroke_y_deg)
         << " deg, cost " << axis_best;
    log(line.str());
  }
  tick();

  // Refine every physical parameter (box stroke, no pan detection), then try the discrete
  // variants (pan detection thresholds, an elliptic stroke) with a short refinement each and
  // refine the best of them fully.
  auto describe = [](const StabiliserModel& c, double cost) {
    const auto& pan = c.get<PanDetectionValues>();
    const auto& stroke = c.get<StrokeValues>();
    const auto& actuator = c.get<ActuatorValues>();
    const Eigen::Matrix2d& g = c.get<CentringValues>().gain;
    std::ostringstream line;
    line << "pan threshold " << pan.pan_detection_rate_rad_s << " rad/s, "
         << (stroke.circular_stroke ? "elliptic" : "box") << " stroke: gain [" << g(0, 0) << " "
         << g(0, 1) << "; " << g(1, 0) << " " << g(1, 1) << "], corner "
         << c.get<CentringValues>().highpass_corner_hz << " Hz, actuator " << actuator.actuator_natural_hz
         << " Hz / " << actuator.actuator_damping << ", lag " << 1000.0 * actuator.sensor_lag_s
         << " ms, stroke " << stroke.stroke_x_deg << " x " << stroke.stroke_y_deg << " deg";
    if (pan.pan_detection_rate_rad_s > 0.0) line << ", release " << pan.pan_release_corner_hz << " Hz";
    line << ", cost " << cost;
    return line.str();
  };
  double refined_cost = 0.0;
  StabiliserModel refined = levenbergMarquardt(best, FreeParameters(), recordings,
                                                    physical_options, options.iterations,
                                                    &refined_cost, &result.rms_history);
  log(describe(refined, refined_cost));
  tick();
  const int short_iterations = std::max(1, options.iterations / 5);
  StabiliserModel variant_best = refined;
  double variant_cost = refined_cost;
  for (double threshold : options.pan_thresholds_rad_s) {
    for (bool circular : {false, true}) {
      if (circular && !options.try_circular_stroke) continue;
      if (threshold <= 0.0 && !circular) continue;  // the refined model itself
      StabiliserModel candidate = refined;
      candidate.get<PanDetectionValues>().pan_detection_rate_rad_s = threshold;
      candidate.get<StrokeValues>().circular_stroke = circular;
      const FreeParameters packing = threshold > 0.0
                                         ? FreeParameters({"pan_detection"})
                                         : FreeParameters();
      double cost = 0.0;
      candidate = levenbergMarquardt(candidate, packing, recordings, physical_options,
                                     short_iterations, &cost);
      log(describe(candidate, cost));
      if (cost < variant_cost) {
        variant_cost = cost;
        variant_best = candidate;
      }
      tick();
    }
  }
  // A variant must earn its extra mechanism: at least 1 % lower cost than the plain model.
  if (variant_cost < 0.99 * refined_cost) {
    const FreeParameters packing = variant_best.get<PanDetectionValues>().pan_detection_rate_rad_s > 0.0
                                       ? FreeParameters({"pan_detection"})
                                       : FreeParameters();
    refined = levenbergMarquardt(variant_best, packing, recordings, physical_options,
                                 options.iterations, &refined_cost, &result.rms_history);
    log("refined: " + describe(refined, refined_cost));
  }

  keepRefined(refined, recordings, options, &result);
  tick();

  const Residuals none_residuals = [&] {
    Residuals r;
    std::vector<double> values;
    for (const StabiliserFitRecording& recording : recordings) {
      const auto predicted = predictLensMotion(refined, recording, options.step_s, options.warm_up_s);
      for (std::size_t k = 0; k < predicted.size(); ++k) {
        if (!predicted[k].allFinite()) continue;
        const double w = std::sqrt(std::max(0.0, recording.observations[k].weight));
        values.push_back(-w * recording.observations[k].motion_px.x());
        values.push_back(-w * recording.observations[k].motion_px.y());
      }
    }
    r.values = Eigen::Map<Eigen::VectorXd>(values.data(), static_cast<long>(values.size()));
    return r;
  }();
  result.rms_without_model_px = weightedRms(none_residuals.values, Eigen::VectorXd::Ones(none_residuals.values.size()));
  result.review = reviewStabiliserFit(result.parameters, options.target);
  if (options.check_timing) {
    checkTiming(refined, recordings, physical_options, &result.review);
  }
  if (std::isfinite(result.review.best_lens_lag_ms)) log(timingCheckSummary(result.review));
  return result;
}

StabiliserFitResult refitStabiliserStages(const StabiliserModel& fitted,
                                          const std::vector<std::string>& stages,
                                          const std::vector<StabiliserFitRecording>& recordings,
                                          const StabiliserFitOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("refitStabiliserStages: " + problem);
  const bool linear_dynamics =
      std::any_of(stages.begin(), stages.end(),
                  [](const std::string& token) { return stageOfToken(token) == "linear_dynamics"; });
  StabiliserModel start = fitted;
  if (linear_dynamics) {
    // Only the listed stages: the linear stage stands in for what the others do not name. Pan
    // detection is the fit's choice wherever there is a centring for it to release.
    std::vector<std::string> kept = stages;
    const bool centring = std::find(stages.begin(), stages.end(), "centring") != stages.end();
    if (centring && start.get<PanDetectionValues>().pan_detection_rate_rad_s > 0.0) kept.push_back("pan_detection");
    start = start.only(kept);
  }
  // Each stage a refit starts: as listed (its variant) or left out.
  for (const StabiliserStage& stage : stabiliserStages()) {
    if (!stage.start) continue;
    const auto listed = std::find_if(stages.begin(), stages.end(), [&](const std::string& token) {
      return stageOfToken(token) == stage.name;
    });
    const std::string variant = listed == stages.end() ? "" : variantOfToken(*listed);
    if (StageValues* own = start.values(stage.name))
      stage.start(*own, listed == stages.end() ? nullptr : variant.c_str());
  }
  std::vector<std::string> free = stages;
  for (const std::string& token : stages) stabiliserStage(stageOfToken(token));  // known names
  if (start.has("pan_detection") && start.get<PanDetectionValues>().pan_detection_rate_rad_s > 0.0)
    free.push_back("pan_detection");
  const FreeParameters packing(free, &start);
  StabiliserFitResult result;
  const Residuals initial = residualsOf(start, recordings, options);
  if (initial.used == 0)
    throw std::invalid_argument("refitStabiliserStages: no usable observation");
  // Step 1 of a composition with the linear stage: its coefficients in closed form, the rest held
  // (kept only when they lower the cost: beside a fitted centring the start is a fit already). A
  // second solve re-linearises the stroke about the first one's lens (a Gauss-Newton step).
  double cost = huberCost(initial.values, options.huber_px);
  if (linear_dynamics) {
    for (int solve = 0; solve < 2; ++solve) {
      StabiliserModel solved = solveLinearDynamicsCoefficients(start, recordings, options);
      const double solved_cost = stabiliserFitCost(solved, recordings, options);
      if (solved_cost < cost) start = std::move(solved), cost = solved_cost;
    }
  }
  // The variant moves the stroke's meaning (where the integrator stops), so the stroke is scanned
  // again around the fitted one before every parameter is refined (`cost` is the start's). With
  // the linear stage the whole grid of the fit is scanned too: the chain's stroke was fitted with a
  // high-pass standing in for the estimator the linear stage now models, and can lie far from the
  // stroke the composition needs (a Kalman design's 1.3 deg fitted as 3 deg by the chain), out of
  // the solver's reach (docs/results/stabiliser_model.md, "Why the fit stops short of the oracle").
  for (int axis = 0; axis < 2; ++axis) {
    const FittedStabiliserParameter& bounds =
        fittedStabiliserParameter(axis == 0 ? "stroke_x_deg" : "stroke_y_deg");
    const StrokeValues& fitted_limits = start.get<StrokeValues>();
    const double fitted_stroke = axis == 0 ? fitted_limits.stroke_x_deg : fitted_limits.stroke_y_deg;
    std::vector<double> strokes;
    for (double factor : {0.7, 0.85, 1.15, 1.3}) strokes.push_back(fitted_stroke * factor);
    if (linear_dynamics) strokes.insert(strokes.end(), strokeScanDeg().begin(), strokeScanDeg().end());
    StabiliserModel scanned = start;
    for (double value : strokes) {
      StabiliserModel candidate = start;
      StrokeValues& limits = candidate.get<StrokeValues>();
      (axis == 0 ? limits.stroke_x_deg : limits.stroke_y_deg) = std::clamp(value, bounds.lower, bounds.upper);
      const double c = stabiliserFitCost(candidate, recordings, options);
      if (c < cost) cost = c, scanned = candidate;
    }
    start = scanned;
  }
  double refined_cost = 0.0;
  if (linear_dynamics) {
    // Step 2.
    const StabiliserModel refined =
        refitWithLinearDynamics(start, packing, recordings, options, &refined_cost, &result.rms_history);
    std::ostringstream line;
    line << "structure:";
    for (const std::string& token : stabiliserComposition(refined)) line << " " << token;
    line << " (two-step fit), cost " << refined_cost;
    result.log.push_back(line.str());
    keepRefined(refined, recordings, options, &result);
    result.review = reviewStabiliserFit(result.parameters, options.target);
    return result;
  }
  const StabiliserModel refined = levenbergMarquardt(start, packing, recordings, options, options.iterations,
                                                     &refined_cost, &result.rms_history);
  std::ostringstream line;
  const auto& stroke = refined.get<StrokeValues>();
  const auto& actuator = refined.get<ActuatorValues>();
  const Eigen::Vector2d& coupling = refined.get<ActuatorCouplingValues>().actuator_coupling;
  line << "structure: " << (stroke.soft_stroke ? "soft stroke, " : "")
       << (stroke.anti_windup ? "anti-windup" : "winding-up") << " integrator, excursion re-centring "
       << refined.get<ExcursionCentringValues>().excursion_centring << ", actuator coupling ("
       << coupling.x() << ", " << coupling.y() << "), corner "
       << refined.get<CentringValues>().highpass_corner_hz << " Hz, actuator "
       << actuator.actuator_natural_hz << " Hz / " << actuator.actuator_damping << ", stroke "
       << stroke.stroke_x_deg << " x " << stroke.stroke_y_deg << " deg, cost " << refined_cost;
  result.log.push_back(line.str());
  keepRefined(refined, recordings, options, &result);
  result.review = reviewStabiliserFit(result.parameters, options.target);
  return result;
}

}  // namespace deep_ois
