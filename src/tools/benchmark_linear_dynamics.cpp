// Benchmarks the linear-dynamics stage (core/ois/linear_dynamics_basis.h) on generated stabiliser
// designs at the level of the lens, on the same traces and measure as benchmark_lens_dynamics: per
// design, the basis and a stroke clip after it fitted in closed form on 6 training traces of 5 s,
// the pole, order and stroke chosen on a 7th, the lens-motion error on 2 evaluation traces beside
// no lens motion and the design's own controller (the oracle), and optionally the chain's
// candidates as benchmark_lens_dynamics fits them. Two fits of the linear stage: from the lens
// itself (a lens log, or the simulator's truth: an upper bound) and from frame-to-frame lens
// motions only (what the images give). Also splits the evaluation error into the first 2 s and
// the rest (is the start, where an estimator's gain settles, what the stage misses?).
// Flags: `benchmark_linear_dynamics --help`; figures and commands: docs/linear_dynamics_stage.md.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/ois/linear_dynamics_basis.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/design_traces.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/design_trace_recording.h"

namespace {

using deep_ois::CameraRateSample;
using deep_ois::LinearDynamicsBasisSpec;
using deep_ois::StabiliserFitRecording;
namespace sim = deep_ois::sim;

// As benchmark_lens_dynamics: the RE camera, 30 fps, 8 row patches, 5 s traces.
struct Settings {
  double focal_px = 257.0;
  double frame_rate_hz = 30.0;
  double readout_s = 0.022;
  int patches = 8;
  double duration_s = 5.0;
  double noise_px = 0.1;
  double step_s = 1e-3;          // the predictor's step
  double settle_s = 2.0;         // samples before this are not fitted on
  double inside_stroke = 0.8;    // nor lens samples beyond this fraction of the stroke
  double ridge = 1e-5;           // relative, fitLinearDynamicsCoefficients' convention
};

// One trace as the linear stage sees it: the basis' states at the gyro stamps and at each
// observation's two ends, for one basis spec.
struct TraceStates {
  Eigen::MatrixXd at_gyro;  // gyro samples x size
  Eigen::MatrixXd at_a, at_b;  // observations x size
};

TraceStates statesOf(const LinearDynamicsBasisSpec& spec, const Settings& s, const StabiliserFitRecording& r) {
  std::vector<double> stamps, times;
  std::vector<Eigen::Vector3d> rates;
  for (const CameraRateSample& g : r.rates) {
    stamps.push_back(g.stamp_s);
    rates.push_back(g.rate_rad_s);
  }
  times = stamps;
  for (const auto& o : r.observations) times.push_back(o.t_a_s);
  for (const auto& o : r.observations) times.push_back(o.t_b_s);
  const Eigen::MatrixXd all = deep_ois::linearDynamicsStates(spec, s.step_s, stamps, rates, times);
  const long g = static_cast<long>(stamps.size()), n = static_cast<long>(r.observations.size());
  return {all.topRows(g), all.middleRows(g, n), all.bottomRows(n)};
}

// The stroke after the linear part, with half-widths per axis and direction (focal units;
// infinite: none): a hard box or ellipse (the lens stops there) or a soft one (L tanh(u / L) per
// axis, or radially), as the generated designs' strokes are.
enum class StrokeShape { kBox, kEllipse, kSoftBox, kSoftEllipse };
const char* toString(StrokeShape shape) {
  switch (shape) {
    case StrokeShape::kBox: return "box";
    case StrokeShape::kEllipse: return "ellipse";
    case StrokeShape::kSoftBox: return "soft box";
    case StrokeShape::kSoftEllipse: return "soft ellipse";
  }
  return "?";
}
struct Stroke {
  StrokeShape shape = StrokeShape::kBox;
  double x_pos = INFINITY, x_neg = INFINITY, y_pos = INFINITY, y_neg = INFINITY;
  bool soft() const { return shape == StrokeShape::kSoftBox || shape == StrokeShape::kSoftEllipse; }
  double limitX(double x) const { return x >= 0.0 ? x_pos : x_neg; }
  double limitY(double y) const { return y >= 0.0 ? y_pos : y_neg; }
  // Per axis, the command over its limit (0 where there is none).
  Eigen::Vector2d excursion(const Eigen::Vector2d& c) const {
    const double lx = limitX(c.x()), ly = limitY(c.y());
    return Eigen::Vector2d(std::isfinite(lx) ? c.x() / lx : 0.0, std::isfinite(ly) ? c.y() / ly : 0.0);
  }
  Eigen::Vector2d apply(const Eigen::Vector2d& c) const {
    const Eigen::Vector2d e = excursion(c);
    switch (shape) {
      case StrokeShape::kBox:
        return Eigen::Vector2d(std::clamp(c.x(), -x_neg, x_pos), std::clamp(c.y(), -y_neg, y_pos));
      case StrokeShape::kEllipse: {
        const double r = e.norm();
        return r > 1.0 ? Eigen::Vector2d(c / r) : c;
      }
      case StrokeShape::kSoftBox:
        return Eigen::Vector2d(e.x() != 0.0 ? c.x() * std::tanh(e.x()) / e.x() : c.x(),
                               e.y() != 0.0 ? c.y() * std::tanh(e.y()) / e.y() : c.y());
      case StrokeShape::kSoftEllipse: {
        const double r = e.norm();
        return r > 1e-12 ? Eigen::Vector2d(c * (std::tanh(r) / r)) : c;
      }
    }
    return c;
  }
  // The command a soft stroke turns into this lens (block-oriented: the static nonlinearity
  // inverted on the lens, so the linear part is fitted to the command), or the lens itself for a
  // hard one. Only for a lens inside the stroke (|excursion| < 1).
  Eigen::Vector2d invert(const Eigen::Vector2d& l) const {
    const Eigen::Vector2d e = excursion(l);
    if (shape == StrokeShape::kSoftBox)
      return Eigen::Vector2d(e.x() != 0.0 ? l.x() * std::atanh(e.x()) / e.x() : l.x(),
                             e.y() != 0.0 ? l.y() * std::atanh(e.y()) / e.y() : l.y());
    if (shape == StrokeShape::kSoftEllipse) {
      const double r = e.norm();
      return r > 1e-12 ? Eigen::Vector2d(l * (std::atanh(r) / r)) : l;
    }
    return l;
  }
  bool inside(const Eigen::Vector2d& c, double fraction) const {
    const Eigen::Vector2d e = excursion(c);
    if (shape == StrokeShape::kEllipse || shape == StrokeShape::kSoftEllipse) return e.norm() < fraction;
    return std::abs(e.x()) < fraction && std::abs(e.y()) < fraction;
  }
  Stroke scaled(double k) const { return {shape, k * x_pos, k * x_neg, k * y_pos, k * y_neg}; }
};

// The widest lens (focal units) per axis and direction over these lenses.
Stroke widest(const std::vector<std::vector<Eigen::Vector2d>>& lenses) {
  Stroke s{StrokeShape::kBox, 0.0, 0.0, 0.0, 0.0};
  for (const auto& lens : lenses)
    for (const Eigen::Vector2d& l : lens) {
      s.x_pos = std::max(s.x_pos, l.x());
      s.x_neg = std::max(s.x_neg, -l.x());
      s.y_pos = std::max(s.y_pos, l.y());
      s.y_neg = std::max(s.y_neg, -l.y());
    }
  // An axis that never moved one way: no limit there.
  for (double* v : {&s.x_pos, &s.x_neg, &s.y_pos, &s.y_neg})
    if (!(*v > 0.0)) *v = INFINITY;
  return s;
}

// Squared-error sums of predicted lens motions (px) against the observations, split at settle_s.
struct ErrorSums {
  double early = 0.0, late = 0.0;
  std::size_t early_n = 0, late_n = 0;
  void add(double t_a, double e2, double settle_s) {
    if (t_a < settle_s) early += e2, ++early_n;
    else late += e2, ++late_n;
  }
  double rms() const { return std::sqrt((early + late) / std::max<std::size_t>(1, early_n + late_n)); }
  double rmsEarly() const { return early_n ? std::sqrt(early / early_n) : NAN; }
  double rmsLate() const { return late_n ? std::sqrt(late / late_n) : NAN; }
  void operator+=(const ErrorSums& o) {
    early += o.early, late += o.late, early_n += o.early_n, late_n += o.late_n;
  }
};

// The linear stage's lens motions on a recording: clip(C x) at both ends, times the focal length.
ErrorSums errorsOf(const Eigen::MatrixXd& c, const Stroke& stroke, const TraceStates& states,
                   const StabiliserFitRecording& r, const Settings& s) {
  const Eigen::MatrixXd lens_a = states.at_a * c.transpose(), lens_b = states.at_b * c.transpose();
  ErrorSums e;
  for (std::size_t i = 0; i < r.observations.size(); ++i) {
    const long k = static_cast<long>(i);
    const Eigen::Vector2d predicted =
        s.focal_px * (stroke.apply(lens_b.row(k).transpose()) - stroke.apply(lens_a.row(k).transpose()));
    e.add(r.observations[i].t_a_s, (predicted - r.observations[i].motion_px).squaredNorm(), s.settle_s);
  }
  return e;
}

ErrorSums errorsAgainst(const StabiliserFitRecording& truth, const StabiliserFitRecording& predicted,
                        const Settings& s) {
  ErrorSums e;
  for (std::size_t i = 0; i < truth.observations.size(); ++i)
    e.add(truth.observations[i].t_a_s,
          (predicted.observations[i].motion_px - truth.observations[i].motion_px).squaredNorm(), s.settle_s);
  return e;
}

// A fitted linear stage and what chose it.
struct LinearStage {
  LinearDynamicsBasisSpec spec;
  Eigen::MatrixXd coefficients;
  Stroke stroke;
  double choice_rms_px = INFINITY;
};

// Rows stacked into a matrix of `cols` columns (none: 0 rows).
template <typename Row>
Eigen::MatrixXd stacked(const std::vector<Row>& rows, long cols) {
  Eigen::MatrixXd m(static_cast<long>(rows.size()), cols);
  for (std::size_t i = 0; i < rows.size(); ++i) m.row(static_cast<long>(i)) = rows[i];
  return m;
}

std::vector<double> parseList(const std::string& text) {
  std::vector<double> v;
  for (double x : deep_ois::splitCommaSeparatedNumbers(text)) v.push_back(x);
  return v;
}

std::string specName(const LinearDynamicsBasisSpec& spec) {  // e.g. "1Hz+10Hz x16"
  char text[64];
  if (spec.second_pole_hz > 0.0)
    std::snprintf(text, sizeof text, "%gHz+%gHz x%d", spec.pole_hz, spec.second_pole_hz, spec.order);
  else
    std::snprintf(text, sizeof text, "%gHz x%d", spec.pole_hz, spec.order);
  return text;
}

std::string stageName(const LinearStage& stage) {
  return specName(stage.spec) + " " + toString(stage.stroke.shape);
}

}  // namespace

constexpr char kDescription[] =
    "Benchmarks the linear-dynamics stage (an orthonormal Laguerre or two-pole basis of the three "
    "gyro axes, fitted in closed form, then a stroke clip) on generated stabiliser designs at the "
    "level of the lens, on benchmark_lens_dynamics' traces and measure: per design, the stage "
    "fitted on 6 training traces of 5 s (samples after --settle s and inside 80 % of the stroke), "
    "the pole, order and stroke chosen on a 7th, then the lens-motion RMS on 2 evaluation traces "
    "beside no lens motion and the design's own controller (the oracle). 'log' fits the stage on "
    "the lens itself (a lens log or the simulator's truth: an upper bound); 'images' only on "
    "frame-to-frame lens motions with --noise px (what the images give). --chain also fits the "
    "chain's candidates as benchmark_lens_dynamics does (slower). 'Closed' is 1 - RMS / RMS "
    "without a lens model; 'early' is the evaluation's first --settle s (from 1 s), 'late' the "
    "rest. Prints a row per design and a summary per class; docs/linear_dynamics_stage.md.";

int main(int argc, char** argv) {
  std::string split = "held_out", csv_path, classes_text;
  std::string poles_text = "0.5,1,2", orders_text = "4,8,12,16", second_text = "0,10,30";
  std::uint32_t seed_begin = 0, count = 40, per_class = 0;
  Settings settings;
  bool chain = false, images = true, describe = false, soft_strokes = true;
  deep_ois::ToolCommandLine command_line("benchmark_linear_dynamics", kDescription);
  CLI::App& app = command_line.app();
  app.add_option("--split", split, "which designs: the generator's held-out seeds (seed % 5 == 0) "
                                   "or its training split")
      ->check(deep_ois::oneOf({"held_out", "training"}))
      ->capture_default_str();
  command_line.addNumber("--seed-begin", seed_begin, "first design seed considered");
  command_line.addNumber("--count", count, "designs of the split from --seed-begin on");
  command_line.addNumber("--per-class", per_class,
                         "at most this many designs per class (0: no limit; counts toward --count)");
  app.add_option("--classes", classes_text, "only these classes, comma-separated (default: all)");
  app.add_option("--poles", poles_text, "basis poles tried, Hz, comma-separated")->capture_default_str();
  app.add_option("--orders", orders_text, "basis orders tried (functions per gyro axis)")->capture_default_str();
  app.add_option("--second-poles", second_text, "second poles tried, Hz (0: Laguerre)")->capture_default_str();
  command_line.addNumber("--ridge", settings.ridge, "ridge, relative to each state's energy");
  command_line.addNumber("--settle", settings.settle_s, "seconds from the start not fitted on (and the "
                                                        "early/late split of the evaluation)");
  command_line.addNumber("--noise", settings.noise_px, "lens-motion measurement noise, px (per axis)");
  app.add_option("--images", images, "also fit from frame-to-frame lens motions only")->capture_default_str();
  app.add_option("--soft-strokes", soft_strokes, "also try soft strokes (tanh) after the linear part")
      ->capture_default_str();
  app.add_option("--chain", chain, "also fit the chain's candidates (as benchmark_lens_dynamics does)")
      ->capture_default_str();
  app.add_flag("--describe", describe, "print each design's description under its row");
  app.add_option("--csv", csv_path, "write the rows here")->type_name("FILE.csv");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    std::vector<double> poles = parseList(poles_text), seconds = parseList(second_text), orders = parseList(orders_text);
    std::set<std::string> classes;
    for (std::size_t start = 0; start <= classes_text.size() && !classes_text.empty();) {
      const std::size_t comma = std::min(classes_text.find(',', start), classes_text.size());
      classes.insert(classes_text.substr(start, comma - start));
      start = comma + 1;
    }
    for (const std::string& c : classes)
      if (std::find(sim::designClasses().begin(), sim::designClasses().end(), c) == sim::designClasses().end())
        return command_line.usageError("--classes: unknown class '" + c + "'");
    std::vector<LinearDynamicsBasisSpec> specs;
    for (double p : poles)
      for (double o : orders)
        for (double q : seconds) {
          LinearDynamicsBasisSpec spec;
          spec.pole_hz = p;
          spec.order = static_cast<int>(o);
          spec.second_pole_hz = q;
          const std::string problem = spec.validate(settings.step_s);
          if (!problem.empty() || o != std::floor(o)) return command_line.usageError("basis grid: " + (problem.empty() ? "orders must be whole" : problem));
          specs.push_back(spec);
        }

    std::ofstream csv;
    if (!csv_path.empty()) {
      csv.open(csv_path);
      if (!csv) throw std::runtime_error("cannot write " + csv_path);
      csv << "design_seed,class,none_px,log_px,images_px,chain_px,oracle_px,closed_log,closed_images,closed_chain,"
             "closed_oracle,log_spec,images_spec,early_none_px,early_log_px,early_oracle_px,late_none_px,late_log_px,"
             "late_oracle_px,seconds\n";
    }
    const sim::DesignSplit wanted = split == "held_out" ? sim::DesignSplit::kHeldOut : sim::DesignSplit::kTraining;
    sim::DesignTraceOptions trace_options;
    trace_options.duration_s = settings.duration_s;
    trace_options.focal_px = settings.focal_px;
    const deep_ois::DesignTraceCamera camera{settings.focal_px, settings.frame_rate_hz, settings.readout_s,
                                             settings.patches};
    deep_ois::StabiliserFitOptions fit_options;
    fit_options.check_timing = false;
    // The chain column is the package's chain without the linear-dynamics rows this tool scores
    // on its own (else "chain" would already hold them).
    deep_ois::StabiliserCandidateKinds kinds;
    kinds.linear_dynamics = false;

    std::printf("%-6s %-22s %8s %8s %8s %8s %8s %7s %7s %7s %7s  %s\n", "design", "class", "none px", "log px",
                "images", "chain", "oracle", "log %", "img %", "chain %", "orac %", "log basis / images basis");
    std::map<std::string, std::vector<double>> by_class[4];  // log, images, chain, oracle
    std::map<std::string, int> designs_of_class;
    ErrorSums early_late[3];  // none, log, oracle over all designs
    std::vector<double> all[4];
    int designs = 0;
    for (std::uint32_t seed = seed_begin; designs < static_cast<int>(count) && seed < seed_begin + 100000; ++seed) {
      if (sim::designSplit(seed) != wanted) continue;
      const sim::StabiliserDesign design = sim::generateDesign(seed);
      const std::string cls = sim::designClass(design);
      if (!classes.empty() && !classes.count(cls)) continue;
      if (per_class > 0 && designs_of_class[cls] >= static_cast<int>(per_class)) continue;
      ++designs_of_class[cls];
      ++designs;
      const auto started = std::chrono::steady_clock::now();
      std::vector<StabiliserFitRecording> training, choice, evaluation, oracle;
      std::vector<std::vector<Eigen::Vector2d>> training_lens;  // focal units, at the gyro stamps
      for (std::uint32_t m = 101; m <= 109; ++m) {
        const sim::DesignTrace trace = sim::simulateDesignTrace(seed, m, trace_options);
        if (m <= 107) {
          (m <= 106 ? training : choice).push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, settings.noise_px, m));
          if (m <= 106) {
            std::vector<Eigen::Vector2d> lens;
            for (const Eigen::Vector2d& l : trace.lens_px) lens.push_back(l / settings.focal_px);
            training_lens.push_back(lens);
          }
        } else {
          evaluation.push_back(deep_ois::designTraceRecording(trace, trace.lens_px, camera, 0.0, m));
          oracle.push_back(deep_ois::designTraceRecording(trace, sim::designLensShifts(design, settings.focal_px, trace.gyro),
                                                camera, 0.0, m));
        }
      }
      const Stroke data_stroke = widest(training_lens);

      // Per spec: the fits, scored on the choice trace; the best of each kind kept.
      LinearStage best_log, best_images;
      for (const LinearDynamicsBasisSpec& spec : specs) {
        std::vector<TraceStates> train_states;
        for (const auto& r : training) train_states.push_back(statesOf(spec, settings, r));
        const TraceStates choice_states = statesOf(spec, settings, choice[0]);
        // From the lens: samples after settle_s. A hard stroke (the widest lens seen): the lens as
        // the target, inside 80 % of it. A soft one (k x the widest lens seen): every sample, the
        // target the command the stroke turns into that lens (its tanh inverted).
        std::vector<Stroke> log_strokes;
        for (StrokeShape shape : {StrokeShape::kBox, StrokeShape::kEllipse}) {
          Stroke stroke = data_stroke;
          stroke.shape = shape;
          log_strokes.push_back(stroke);
        }
        if (soft_strokes)
          for (double k : {1.05, 1.25, 1.6})
            for (StrokeShape shape : {StrokeShape::kSoftBox, StrokeShape::kSoftEllipse}) {
              Stroke stroke = data_stroke.scaled(k);
              stroke.shape = shape;
              log_strokes.push_back(stroke);
            }
        for (const Stroke& stroke : log_strokes) {
          std::vector<Eigen::RowVectorXd> rows;
          std::vector<Eigen::RowVector2d> targets;
          for (std::size_t r = 0; r < training.size(); ++r)
            for (std::size_t i = 0; i < training[r].rates.size(); ++i) {
              const Eigen::Vector2d& lens = training_lens[r][i];
              if (training[r].rates[i].stamp_s < settings.settle_s) continue;
              if (!stroke.inside(lens, stroke.soft() ? 1.0 : settings.inside_stroke)) continue;
              rows.push_back(train_states[r].at_gyro.row(static_cast<long>(i)));
              targets.push_back(stroke.invert(lens).transpose());
            }
          const Eigen::MatrixXd x = stacked(rows, train_states[0].at_gyro.cols()), y = stacked(targets, 2);
          if (x.rows() <= x.cols()) continue;
          const Eigen::MatrixXd c = deep_ois::fitLinearDynamicsCoefficients(x, y, {}, settings.ridge);
          const double rms = errorsOf(c, stroke, choice_states, choice[0], settings).rms();
          if (rms < best_log.choice_rms_px) best_log = {spec, c, stroke, rms};
        }
        // From the lens motions alone: differences of the states against the observed motions
        // (focal units), first on every pair after settle_s; then the stroke (a scale of the widest
        // predicted lens, and its shape) chosen with a refit on the pairs whose predicted lens
        // stays inside 80 % of it at both ends.
        if (images) {
          // Whole pairs first.
          std::vector<Eigen::RowVectorXd> rows;
          std::vector<Eigen::RowVector2d> targets;
          std::vector<std::pair<std::size_t, long>> where;
          for (std::size_t r = 0; r < training.size(); ++r)
            for (std::size_t i = 0; i < training[r].observations.size(); ++i) {
              const auto& o = training[r].observations[i];
              if (o.t_a_s < settings.settle_s) continue;
              const long k = static_cast<long>(i);
              rows.push_back(train_states[r].at_b.row(k) - train_states[r].at_a.row(k));
              targets.push_back(o.motion_px.transpose() / settings.focal_px);
              where.emplace_back(r, k);
            }
          const Eigen::MatrixXd x = stacked(rows, train_states[0].at_a.cols()), y = stacked(targets, 2);
          if (x.rows() <= x.cols()) continue;
          const Eigen::MatrixXd first = deep_ois::fitLinearDynamicsCoefficients(x, y, {}, settings.ridge);
          // The widest predicted lens on the training gyro.
          std::vector<std::vector<Eigen::Vector2d>> predicted;
          for (const TraceStates& t : train_states) {
            const Eigen::MatrixXd lens = t.at_gyro * first.transpose();
            std::vector<Eigen::Vector2d> p;
            for (long i = 0; i < lens.rows(); ++i) p.push_back(lens.row(i).transpose());
            predicted.push_back(p);
          }
          const Stroke reach = widest(predicted);
          for (double k : {0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1e9}) {
            Stroke stroke = reach.scaled(k);
            Eigen::VectorXd w = Eigen::VectorXd::Ones(x.rows());
            if (k < 1e8) {
              for (std::size_t i = 0; i < where.size(); ++i) {
                const TraceStates& t = train_states[where[i].first];
                const Eigen::Vector2d a = first * t.at_a.row(where[i].second).transpose();
                const Eigen::Vector2d b = first * t.at_b.row(where[i].second).transpose();
                if (!(stroke.inside(a, settings.inside_stroke) && stroke.inside(b, settings.inside_stroke))) w(static_cast<long>(i)) = 0.0;
              }
              if (w.sum() <= 2.0 * x.cols()) continue;
            }
            const Eigen::MatrixXd c = k < 1e8 ? deep_ois::fitLinearDynamicsCoefficients(x, y, w, settings.ridge) : first;
            for (StrokeShape shape : {StrokeShape::kBox, StrokeShape::kEllipse, StrokeShape::kSoftBox,
                                      StrokeShape::kSoftEllipse}) {
              if (!soft_strokes && (shape == StrokeShape::kSoftBox || shape == StrokeShape::kSoftEllipse)) continue;
              stroke.shape = shape;
              const double rms = errorsOf(c, stroke, choice_states, choice[0], settings).rms();
              if (rms < best_images.choice_rms_px) best_images = {spec, c, stroke, rms};
              if (k > 1e8) break;  // no stroke: one shape
            }
          }
        }
      }

      // Evaluation.
      ErrorSums none, log_e, images_e, oracle_e;
      for (std::size_t r = 0; r < evaluation.size(); ++r) {
        StabiliserFitRecording zero = evaluation[r];
        for (auto& o : zero.observations) o.motion_px.setZero();
        none += errorsAgainst(evaluation[r], zero, settings);
        oracle_e += errorsAgainst(evaluation[r], oracle[r], settings);
        log_e += errorsOf(best_log.coefficients, best_log.stroke, statesOf(best_log.spec, settings, evaluation[r]),
                          evaluation[r], settings);
        if (images)
          images_e += errorsOf(best_images.coefficients, best_images.stroke,
                               statesOf(best_images.spec, settings, evaluation[r]), evaluation[r], settings);
      }
      double chain_rms = NAN;
      if (chain) {
        const deep_ois::StabiliserFitResult fit = deep_ois::fitStabiliser(training, fit_options);
        const deep_ois::StabiliserSelection selection =
            deep_ois::selectStabiliser(fit, training, choice, fit_options, {}, kinds);
        chain_rms = deep_ois::scoreStabiliser(selection.candidates[selection.kept].parameters, evaluation, fit_options).rms_px;
      }
      auto closed = [&](double v) { return 100.0 * (1.0 - v / none.rms()); };
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      const double images_rms = images ? images_e.rms() : NAN;
      std::printf("%-6u %-22s %8.4f %8.4f %8.4f %8.4f %8.4f %6.1f%% %6.1f%% %6.1f%% %6.1f%%  %s / %s (%.0f s)\n", seed,
                  cls.c_str(), none.rms(), log_e.rms(), images_rms, chain_rms, oracle_e.rms(), closed(log_e.rms()),
                  closed(images_rms), closed(chain_rms), closed(oracle_e.rms()), stageName(best_log).c_str(),
                  images ? stageName(best_images).c_str() : "-", secs);
      std::printf("       early (%.0f-%.0f s) / late: none %.4f / %.4f px, log %.4f / %.4f px, oracle %.4f / %.4f px\n",
                  1.0, settings.settle_s, none.rmsEarly(), none.rmsLate(), log_e.rmsEarly(), log_e.rmsLate(),
                  oracle_e.rmsEarly(), oracle_e.rmsLate());
      if (describe) {
        std::string tags;
        for (const std::string& tag : sim::designFeatures(design)) tags += " " + tag;
        std::printf("       features:%s\n       %s\n", tags.c_str(), sim::describe(design).c_str());
      }
      std::fflush(stdout);
      const double values[4] = {closed(log_e.rms()), closed(images_rms), closed(chain_rms), closed(oracle_e.rms())};
      for (int k = 0; k < 4; ++k) {
        if (std::isnan(values[k])) continue;
        by_class[k][cls].push_back(values[k]);
        all[k].push_back(values[k]);
      }
      early_late[0] += none;
      early_late[1] += log_e;
      early_late[2] += oracle_e;
      if (csv)
        csv << seed << "," << cls << "," << none.rms() << "," << log_e.rms() << "," << images_rms << "," << chain_rms
            << "," << oracle_e.rms() << "," << values[0] << "," << values[1] << "," << values[2] << "," << values[3]
            << ",\"" << stageName(best_log) << "\",\"" << (images ? stageName(best_images) : "") << "\","
            << none.rmsEarly() << "," << log_e.rmsEarly() << "," << oracle_e.rmsEarly() << "," << none.rmsLate() << ","
            << log_e.rmsLate() << "," << oracle_e.rmsLate() << "," << secs << "\n";
    }
    auto med = [](const std::vector<double>& v) { return v.empty() ? NAN : deep_ois::median(v); };
    std::printf("\nper class (median closed: linear from the lens / linear from images / chain / oracle):\n");
    for (const auto& [cls, n] : designs_of_class)
      std::printf("  %-22s %2d designs  %6.1f %% / %6.1f %% / %6.1f %% / %6.1f %%\n", cls.c_str(), n,
                  med(by_class[0][cls]), med(by_class[1][cls]), med(by_class[2][cls]), med(by_class[3][cls]));
    std::printf("all %d designs (%s split): median closed %.1f %% from the lens, %.1f %% from images, "
                "chain %.1f %%, oracle %.1f %%\n",
                designs, split.c_str(), med(all[0]), med(all[1]), med(all[2]), med(all[3]));
    std::printf("pooled over the designs, early (1-%.0f s) / late RMS: none %.4f / %.4f px, linear from the lens "
                "%.4f / %.4f px, oracle %.4f / %.4f px\n",
                settings.settle_s, early_late[0].rmsEarly(), early_late[0].rmsLate(), early_late[1].rmsEarly(),
                early_late[1].rmsLate(), early_late[2].rmsEarly(), early_late[2].rmsLate());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_linear_dynamics: %s\n", e.what());
    return 1;
  }
  return 0;
}
