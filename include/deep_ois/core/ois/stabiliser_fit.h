// Learning a camera's stabiliser (core/ois/stabiliser_model.h) from observed lens motion: the
// per-row-patch lens shifts between frames that the gyro-anchored ground truth estimates from
// point tracks (core/ground_truth/lens_shift_ground_truth.h) or that a camera logs.
//
// Why lens motion and not lens position: image motion between two frames only sees the lens'
// change s(t_b) - s(t_a) (to first order), so that is what the images measure well and what the
// compensation needs.
//
// The fit: Levenberg-Marquardt with Huber weights over the physical parameters (gain matrix,
// centring corner, actuator, sensor lag, stroke), the rate at which pan detection lets go chosen
// from a grid (its hysteresis makes the cost step-like in the threshold). Pure C++/Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/core/common/nonlinear_least_squares.h"
#include "deep_ois/core/common/progress_callback.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

// The lens moved by `motion_px` between t_a and t_b (IMU clock, seconds; t_a < t_b).
struct LensMotionObservation {
  double t_a_s = 0.0;
  double t_b_s = 0.0;
  Eigen::Vector2d motion_px = Eigen::Vector2d::Zero();
  double weight = 1.0;
  // Where the observed row patch lies in its frame's readout (0 first row, 1 last row): a wrong
  // readout time misplaces t_a and t_b in proportion to it (the fit's timing check).
  double readout_fraction = 0.5;
};

// Where the observed lens motions come from: the images (gyro-anchored ground truth), the
// camera's own lens-shift log, or the simulator's truth. A fit's review blames what can be wrong
// with that source (the camera-IMU calibration for the images, the log's convention and clock for a
// log) and nothing else.
enum class LensMotionTarget { kImages, kLensLog, kSimulatorTruth };
// The command-line names: "images", "log", "truth" (throws std::invalid_argument for others).
LensMotionTarget lensMotionTargetNamed(const std::string& name);
const char* lensMotionTargetName(LensMotionTarget target);

// One recording: its gyro stream (camera frame, increasing stamps) and what was observed.
struct StabiliserFitRecording {
  std::string name;  // for messages
  double focal_px = 0.0;
  std::vector<CameraRateSample> rates;
  std::vector<LensMotionObservation> observations;  // any order
};

struct StabiliserFitOptions {
  double huber_px = 0.3;         // Huber threshold on an observation's residual norm, pixels
  int iterations = 30;           // solver iterations per candidate (nonlinear_least_squares.h)
  SolverEngine solver_engine = SolverEngine::kLevenbergMarquardt;  // the minimiser under the solver
  // Pan-detection thresholds tried (rad/s); 0 = pan detection off.
  std::vector<double> pan_thresholds_rad_s = {0.0, 0.3, 0.6, 1.2};
  bool try_circular_stroke = true;
  double step_s = 1e-3;  // the model's integration step (as LensShiftPredictor's)
  // Observations in the first warm_up_s of a recording's gyro stream are not used: the model
  // starts from a centred lens, the real stabiliser did not.
  double warm_up_s = 1.0;
  // The timing check of the review (a few dozen cost evaluations after the fit).
  bool check_timing = true;
  // The readout time the observations were placed with (the gyro config's), seconds: the timing
  // check names a readout that fits better in proportion to it; 0 = unknown.
  double readout_time_s = 0.0;
  // What the observations are (the review's and the timing check's wording).
  LensMotionTarget target = LensMotionTarget::kImages;

  std::string validate() const;
};

// What a fit's parameters say beyond its residual (a fit says how it ended): each list holds one
// sentence per finding, for the training report.
struct StabiliserFitReview {
  // Parameters that ended on a bound of the fit (they wanted to go further), e.g. "sensor lag
  // 0.00 ms is the fit's lower bound"; `on_bound_parameters` names them as StabiliserModel
  // does ("sensor_lag_s", "actuator_damping", ...) for tables.
  std::vector<std::string> on_bound;
  std::vector<std::string> on_bound_parameters;
  // Values outside what a camera module does (a gain far from 1, a stroke beyond a module's
  // travel), each with its likely cause.
  std::vector<std::string> implausible;
  // The timing check (fitStabiliser only): the observations moved in time against the gyro, with
  // the fitted physical model and no sensor lag. A time shift of the whole frame (at its middle
  // row) and a change of the readout (rows moved in proportion to their place in the readout) are
  // scanned. The lens must then lag the gyro by a module's sensor lag (a time offset error adds to
  // it), and the readout must need no change. Milliseconds; NaN when not checked.
  double best_lens_lag_ms = std::numeric_limits<double>::quiet_NaN();
  double best_readout_change_ms = std::numeric_limits<double>::quiet_NaN();
  // A sentence per suspect setting (time_offset, readout_time) with what the data prefer.
  std::vector<std::string> timing;

  bool onBound(const std::string& parameter) const;
};

// The timing check's finding in one line, for logs ("timing check: the lens motion fits best
// 2.6 ms ahead of the gyro, with the readout changed by 0.3 ms"); a value on the end of the scanned
// range says so (the cost kept falling: no optimum inside it). "timing check: not run" when NaN.
std::string timingCheckSummary(const StabiliserFitReview& review);

// Reviews fitted parameters: bounds of the fit reached (pan_release_corner_hz only with pan
// detection on, the only case the fit moves it) and implausible values, each with the causes that
// apply to lens motions from `target`.
StabiliserFitReview reviewStabiliserFit(const StabiliserModel& parameters,
                                        LensMotionTarget target = LensMotionTarget::kImages);

struct StabiliserFitResult {
  StabiliserModel parameters;
  std::size_t observations_used = 0;
  std::size_t observations_skipped = 0;  // before the warm-up or outside the gyro stream
  // Root mean square of the observations' residual norm (pixels, weighted): with no lens model
  // (motion 0, what the uncompensated gyro assumes) and with the fitted model.
  double rms_without_model_px = 0.0;
  double rms_px = 0.0;
  std::vector<std::string> log;  // one line per candidate tried, for the training report
  // The RMS residual (pixels) after every accepted refinement step of the model kept (the first
  // refinement, the full one, and the variant's when one was kept): the fit's loss curve.
  std::vector<double> rms_history;
  StabiliserFitReview review;  // of `parameters`
};

// Throws std::invalid_argument when the options are invalid, a recording has no focal length or
// non-increasing rate stamps, or no observation is usable (the message says why).
StabiliserFitResult fitStabiliser(const std::vector<StabiliserFitRecording>& recordings,
                                  const StabiliserFitOptions& options,
                                  const ProgressCallback& progress = {});

// The chain of `fitted` (a fitStabiliser result) composed of `stages` (stage tokens, as
// stabiliserComposition writes them: {"excursion_centring", "centring", "stroke:soft",
// "actuator"}): each stage that a refit starts (StabiliserStage::start) set up as listed or left
// out, refined by Levenberg-Marquardt from fitted's physical parameters with the listed stages'
// parameters free (the stroke scanned again around them, pan detection and stroke shape kept). The
// training RMS and the review are filled;
// rms_without_model_px and the timing check are not (they do not depend on the composition).
//
// With a linear-dynamics stage among `stages` ("linear_dynamics:1hz_x8", its basis as the variant)
// the model has only the listed stages (and the fit's pan detection when the centring is listed),
// and the fit has two steps (docs/stabiliser_model.md, "The fit's two steps"): first its
// coefficients in closed form with the rest of the chain held (solveLinearDynamicsCoefficients from
// zero, twice: the second solve sees where the first one's lens meets the stroke), then the whole
// chain jointly by block coordinate descent: the solver moves the other stages' parameters with
// the coefficients held, the coefficients are solved again in closed form with the others held,
// and so on while the cost falls (each block's step is kept only when it lowers the cost).
// Throws std::invalid_argument as fitStabiliser, and for an unknown stage or variant.
StabiliserFitResult refitStabiliserStages(const StabiliserModel& fitted,
                                          const std::vector<std::string>& stages,
                                          const std::vector<StabiliserFitRecording>& recordings,
                                          const StabiliserFitOptions& options);

// The linear-dynamics stage's coefficients (stages/linear_dynamics_stage.cpp) solved in closed form
// with every other stage of `model` held: the lens motion is linearised in the coefficients about
// their current values (one run of the chain per coefficient column, a small probe added to both
// rows), and each image axis' row is the package's robust ridge regression
// (RobustRidgeRegression: `ridge` relative to each column's energy, Huber weights from the
// current residual as options.huber_px) on motion - lens(C) + J C. Exact when the chain is linear
// in the coefficients (inside the stroke); through a stroke the lens that meets the end stop has
// no slope, so those motions drop out of the solve. Returns `model` with the solved coefficients
// (unchanged when the solve is not finite); the caller keeps them only if they lower its cost.
// Throws std::invalid_argument when the model has no active linear-dynamics stage or fewer usable
// lens motions than coefficients.
StabiliserModel solveLinearDynamicsCoefficients(const StabiliserModel& model,
                                                const std::vector<StabiliserFitRecording>& recordings,
                                                const StabiliserFitOptions& options, double ridge = 1e-5);

// A model's RMS lens-motion residual on recordings (pixels, weighted by the observations'
// weights) beside that of no lens motion (motion 0), over the observations the model predicts.
struct StabiliserScore {
  double rms_px = std::numeric_limits<double>::quiet_NaN();
  double rms_without_model_px = std::numeric_limits<double>::quiet_NaN();
  std::size_t observations = 0;
};
StabiliserScore scoreStabiliser(const StabiliserModel& parameters,
                                const std::vector<StabiliserFitRecording>& recordings,
                                const StabiliserFitOptions& options);

// The model of a camera whose lens does not move (no OIS, or OIS off): gain 0, no residual, no
// pan detection: the compensation is the plain gyro. Always a candidate: a fit must beat it on
// recordings it was not trained on (checkFitAgainstNoLensMotion, stabiliser_model_choice.h).
StabiliserModel noLensMotion();

// The fit's robust cost of `parameters` on `recordings` (what fitStabiliser minimises): 1/2 sum of
// Huber(|predicted - observed lens motion|^2, options.huber_px) over the observations the model
// predicts, each weighted by its weight (the solver's convention, nonlinear_least_squares.h).
double stabiliserFitCost(const StabiliserModel& parameters,
                         const std::vector<StabiliserFitRecording>& recordings,
                         const StabiliserFitOptions& options);

// The model's predicted lens motion for each observation of `recording` (in input order; NaN for
// those it cannot predict: before the gyro stream's warm-up or outside it).
std::vector<Eigen::Vector2d> predictLensMotion(const StabiliserModel& parameters,
                                               const StabiliserFitRecording& recording,
                                               double step_s = 1e-3, double warm_up_s = 1.0);

// How the fit and every closed-form stage fit see a recording: a predictor of `parameters` fed
// `recording`'s gyro (its own gaps fed, not restarted) in the order of the observations' ends, and
// `visit(predictor, observation index)` for each observation past the warm-up whose two ends the
// predictor covers. `prepare`, when given, runs on the new predictor before the first rate (for
// example to record its features or its learned state).
void visitCoveredObservations(const StabiliserModel& parameters, const StabiliserFitRecording& recording,
                              double step_s, double warm_up_s,
                              const std::function<void(const LensShiftPredictor&, std::size_t)>& visit,
                              const std::function<void(LensShiftPredictor&)>& prepare = {});

}  // namespace deep_ois
