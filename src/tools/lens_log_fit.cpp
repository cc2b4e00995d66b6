// Learns a phone's stabiliser from its own gyro and OIS lens log (the layout of Google's
// deep-stabilization data, e.g. ../shared/data/pixel4_dvs_ois; no frames needed) and scores it on
// held-out time: trained on the first SPLIT seconds and scored on the rest, then the reverse.
// Every candidate of core/ois/stabiliser_candidates.h is scored (R^2 of the lens motion over one
// frame interval and of the lens position), the predicted and logged lens are written as CSV and
// PNG per fold, and the model of the first fold is written when --out is given. It also prints
// the log's noise ceiling (the R^2 an exact model would reach against the log's own noise) and,
// per fold, the fit's timing check on the training time (--fit-time-offset applies it).
//
// The gyro is used over the whole log in both folds (the stabiliser's state needs its history and
// the gyro is always there); only the lens labels are split.


#include <algorithm>
#include <cmath>
#include <memory>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_log_time_fit.h"
#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/recording/android_ois_log.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/csv_plot.h"

namespace {

using deep_ois::LoggedLensSample;

// Lens motions between each logged sample in [from, to) and the first one `interval_s` or more
// later (also inside the window).
std::vector<deep_ois::LensMotionObservation> motionsIn(const std::vector<LoggedLensSample>& lens,
                                                       double from, double to, double interval_s) {
  std::vector<deep_ois::LensMotionObservation> motions;
  std::size_t j = 0;
  for (std::size_t i = 0; i < lens.size(); ++i) {
    if (lens[i].stamp_s < from) continue;
    j = std::max(j, i + 1);
    while (j < lens.size() && lens[j].stamp_s - lens[i].stamp_s < interval_s) ++j;
    if (j >= lens.size() || lens[j].stamp_s >= to) break;
    deep_ois::LensMotionObservation o;
    o.t_a_s = lens[i].stamp_s;
    o.t_b_s = lens[j].stamp_s;
    o.motion_px = lens[j].shift_px - lens[i].shift_px;
    motions.push_back(o);
  }
  return motions;
}

// The model's lens position at each of `times` (increasing), fed the whole gyro stream.
std::vector<Eigen::Vector2d> positionsAt(const deep_ois::StabiliserModel& parameters,
                                         const deep_ois::AndroidOisLog& log,
                                         const std::vector<double>& times) {
  deep_ois::LensShiftPredictor predictor(parameters, log.focal_px, 1e-3, 0.5);
  predictor.max_gap_s = std::numeric_limits<double>::infinity();
  std::vector<Eigen::Vector2d> out;
  std::size_t next = 0;
  for (double t : times) {
    while (next < log.rates.size() && (!predictor.started() || predictor.newestStamp() < t))
      predictor.addRate(log.rates[next++]);
    out.push_back(predictor.covers(t) ? predictor.lensShiftAt(t)
                                      : Eigen::Vector2d::Constant(std::nan("")));
  }
  return out;
}

struct RSquared {
  double motion = std::nan(""), position = std::nan("");
  std::size_t samples = 0;
};

// R^2 of the lens motion (observations) and of the position (a constant offset removed: the
// model starts centred, the log's zero need not be the lens' rest).
RSquared scoreFold(const deep_ois::StabiliserModel& parameters,
                   const deep_ois::StabiliserFitRecording& scored, const deep_ois::AndroidOisLog& log,
                   double from, double to, double warm_up_s) {
  RSquared r;
  const auto predicted = deep_ois::predictLensMotion(parameters, scored, 1e-3, warm_up_s);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  std::size_t n = 0;
  for (std::size_t k = 0; k < predicted.size(); ++k)
    if (predicted[k].allFinite()) mean += scored.observations[k].motion_px, ++n;
  if (n == 0) return r;
  mean /= static_cast<double>(n);
  double error = 0.0, spread = 0.0;
  for (std::size_t k = 0; k < predicted.size(); ++k) {
    if (!predicted[k].allFinite()) continue;
    error += (predicted[k] - scored.observations[k].motion_px).squaredNorm();
    spread += (scored.observations[k].motion_px - mean).squaredNorm();
  }
  r.motion = 1.0 - error / spread;
  std::vector<double> times;
  std::vector<Eigen::Vector2d> logged;
  const double usable = log.rates.front().stamp_s + warm_up_s;
  for (const LoggedLensSample& s : log.lens)
    if (s.stamp_s >= std::max(from, usable) && s.stamp_s < to) times.push_back(s.stamp_s), logged.push_back(s.shift_px);
  const auto positions = positionsAt(parameters, log, times);
  Eigen::Vector2d offset = Eigen::Vector2d::Zero(), log_mean = Eigen::Vector2d::Zero();
  n = 0;
  for (std::size_t k = 0; k < times.size(); ++k)
    if (positions[k].allFinite()) offset += logged[k] - positions[k], log_mean += logged[k], ++n;
  if (n == 0) return r;
  offset /= static_cast<double>(n);
  log_mean /= static_cast<double>(n);
  error = spread = 0.0;
  for (std::size_t k = 0; k < times.size(); ++k) {
    if (!positions[k].allFinite()) continue;
    error += (positions[k] + offset - logged[k]).squaredNorm();
    spread += (logged[k] - log_mean).squaredNorm();
  }
  r.position = 1.0 - error / spread;
  r.samples = n;
  return r;
}

// How well any model could score: an upper bound of the log's own noise per sample (pixels RMS
// per axis) from each sample's distance to the line through its neighbours (white noise of
// variance s^2 gives (1 + a^2 + b^2) s^2 for the interpolation weights a + b = 1; the lens' own
// curvature only adds to it, so this bounds the noise from above), and the R^2 of the lens motion
// that noise alone leaves (each motion is a difference of two samples: 2 s^2 per axis), a lower
// bound of the ceiling.
struct NoiseCeiling {
  Eigen::Vector2d noise_px = Eigen::Vector2d::Constant(std::nan(""));
  double r_squared_motion = std::nan("");
};
NoiseCeiling noiseCeiling(const std::vector<LoggedLensSample>& lens,
                          const std::vector<deep_ois::LensMotionObservation>& motions) {
  NoiseCeiling c;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  std::size_t n = 0;
  for (std::size_t i = 1; i + 1 < lens.size(); ++i) {
    const double span = lens[i + 1].stamp_s - lens[i - 1].stamp_s;
    if (!(span > 0.0)) continue;
    const double b = (lens[i].stamp_s - lens[i - 1].stamp_s) / span, a = 1.0 - b;
    const Eigen::Vector2d r = lens[i].shift_px - (a * lens[i - 1].shift_px + b * lens[i + 1].shift_px);
    sum += r.cwiseAbs2() / (1.0 + a * a + b * b);
    ++n;
  }
  if (n == 0 || motions.empty()) return c;
  c.noise_px = (sum / static_cast<double>(n)).cwiseSqrt();
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& m : motions) mean += m.motion_px;
  mean /= static_cast<double>(motions.size());
  double spread = 0.0;
  for (const auto& m : motions) spread += (m.motion_px - mean).squaredNorm();
  spread /= static_cast<double>(motions.size());
  c.r_squared_motion = 1.0 - 2.0 * c.noise_px.squaredNorm() / spread;
  return c;
}

// Predicted (offset as scored) and logged lens on a 5 ms grid over [from, to): CSV and PNG.
void writeTrajectory(const deep_ois::StabiliserModel& parameters, const deep_ois::AndroidOisLog& log,
                     double from, double to, const std::string& prefix, const std::string& title) {
  std::vector<double> times;
  for (double t = from; t < to; t += 0.005) times.push_back(t);
  const auto predicted = positionsAt(parameters, log, times);
  {
    std::ofstream csv(prefix + ".csv");
    csv << "t_s,predicted_x_px,predicted_y_px,logged_x_px,logged_y_px\n";
    std::size_t j = 0;
    for (std::size_t k = 0; k < times.size(); ++k) {
      while (j + 1 < log.lens.size() && log.lens[j + 1].stamp_s <= times[k]) ++j;
      Eigen::Vector2d logged = log.lens[j].shift_px;
      if (j + 1 < log.lens.size() && log.lens[j].stamp_s <= times[k]) {
        const double a = (times[k] - log.lens[j].stamp_s) / (log.lens[j + 1].stamp_s - log.lens[j].stamp_s);
        logged = (1.0 - a) * log.lens[j].shift_px + a * log.lens[j + 1].shift_px;
      }
      csv << times[k] - log.rates.front().stamp_s << "," << predicted[k].x() << "," << predicted[k].y()
          << "," << logged.x() << "," << logged.y() << "\n";
    }
    if (!csv) throw std::runtime_error(prefix + ".csv: cannot write");
  }
  deep_ois::CsvPlot plot;
  plot.title = title;
  plot.x_column = "t_s";
  plot.x_label = "time since the gyro log's first sample [s]";
  plot.y_labels = {"lens shift x [px]", "lens shift y [px]"};
  plot.curves = {{"logged_x_px", "logged x", deep_ois::PlotRole::kLogged, 1},
                 {"predicted_x_px", "predicted x", deep_ois::PlotRole::kPredicted, 1},
                 {"logged_y_px", "logged y", deep_ois::PlotRole::kLogged, 2},
                 {"predicted_y_px", "predicted y", deep_ois::PlotRole::kPredicted, 2}};
  plot.width_px = 1200;
  plot.height_px = 600;
  const deep_ois::PlotOutcome outcome = deep_ois::plotCsv(plot, prefix + ".csv", prefix + ".png");
  if (!outcome.written)
    std::fprintf(stderr, "lens_log_fit: %s\n", deep_ois::describePlot(outcome, prefix + ".csv", prefix + ".png").c_str());
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "lens_log_fit",
      "Learns a phone's stabiliser from its gyro and OIS lens log (deep-stabilization layout: "
      "gyro_log_*.txt, ois_log_*.txt, calib.txt) and scores every stabiliser-model candidate on "
      "held-out time in two folds (first SPLIT s / rest, and the reverse): R^2 of the lens motion "
      "over one frame interval and of the lens position; and the R^2 the log's own noise leaves "
      "(its noise ceiling).",
      "Exit status: 0 done, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  std::string folder, out_path, plots;
  deep_ois::AndroidOisLogOptions log_options;
  double split_s = 6.0, interval_s = 1.0 / 30.0, lens_time_offset_s = 0.0;
  deep_ois::StabiliserFitOptions fit_options;
  fit_options.target = deep_ois::LensMotionTarget::kLensLog;  // the review blames the log's convention
  app.add_option("--log", folder, "the log folder")->required()->check(deep_ois::existingDirectory());
  command_line.addNumber("--split", split_s, "seconds from the start of the gyro log")
      ->check(deep_ois::greaterThan(0));
  command_line.addNumber("--interval", interval_s, "lens-motion interval, s (one frame)")
      ->check(deep_ois::greaterThan(0));
  command_line.addNumber("--image-width", log_options.image_width_px,
                         "image width the lens is scaled to (scale = width / active-array width)")
      ->check(deep_ois::greaterThan(0));
  command_line.addNumber("--active-array-width", log_options.active_array_width_px,
                         "the sensor's active-array width, pixels")
      ->check(deep_ois::greaterThan(0));
  command_line.addNumber("--lens-time-offset", lens_time_offset_s,
                         "seconds added to the lens log's stamps (as the gyro config's "
                         "lens_shift_time_offset); each fold's timing check says what its training "
                         "time prefers");
  command_line.addNumber("--warm-up", fit_options.warm_up_s, "seconds of gyro before a scored motion")
      ->check(deep_ois::atLeast(0));
  bool fit_time_offset = false;
  app.add_flag("--fit-time-offset", fit_time_offset,
               "per fold, move the lens log by what the fit's timing check finds on the training "
               "time (never the held-out time), then fit again");
  app.add_option("--out", out_path, "write the first fold's kept model here")->type_name("MODEL.yaml");
  app.add_option("--plots", plots, "write PREFIX_fold<N>.csv/.png: predicted and logged lens")
      ->type_name("PREFIX");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  deep_ois::StabiliserCandidateKinds kinds;
  if (!out_path.empty()) {
    try {  // now, not after the fit: a mistyped --out folder must not cost the fit
      deep_ois::StabiliserModelFile::checkSavable(out_path);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lens_log_fit: --out: %s\n", e.what());
      return 1;
    }
  }

  deep_ois::AndroidOisLog log;
  try {
    log = deep_ois::readAndroidOisLog(folder, log_options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lens_log_fit: %s\n", e.what());
    return 1;
  }
  for (LoggedLensSample& sample : log.lens) sample.stamp_s += lens_time_offset_s;
  std::printf("%s: %zu gyro samples, %zu lens rows: %zu repeats dropped, %zu steps back in file "
              "order (sorted); focal %.1f px\n\n",
              folder.c_str(), log.rates.size(), log.lens_rows,
              log.lens_repeats_dropped, log.lens_out_of_order, log.focal_px);
  const double t0 = log.rates.front().stamp_s, t_split = t0 + split_s, t_end = log.rates.back().stamp_s;
  auto recording = [&](const deep_ois::AndroidOisLog& from_log, double from, double to, const char* name) {
    deep_ois::StabiliserFitRecording r;
    r.name = name;
    r.focal_px = from_log.focal_px;
    r.rates = from_log.rates;
    r.observations = motionsIn(from_log.lens, from, to, interval_s);
    return r;
  };
  {
    const NoiseCeiling ceiling = noiseCeiling(log.lens, motionsIn(log.lens, t0, t_end + 1.0, interval_s));
    std::printf("The log's noise is at most %.2f / %.2f px RMS per sample (x / y, from each sample's "
                "distance to the line through its neighbours): a model that is exact would still "
                "score at least R^2 %.4f of the lens motion (the noise ceiling).\n\n",
                ceiling.noise_px.x(), ceiling.noise_px.y(), ceiling.r_squared_motion);
  }
  std::printf("| fold | candidate | training lens-motion RMS px | held-out RMS px | R^2 motion | R^2 position |\n");
  std::printf("|---|---|---:|---:|---:|---:|\n");
  int status = 0;
  for (int fold = 1; fold <= 2; ++fold) {
    const double train_from = fold == 1 ? t0 : t_split, train_to = fold == 1 ? t_split : t_end + 1.0;
    const double test_from = fold == 1 ? t_split : t0, test_to = fold == 1 ? t_end + 1.0 : t_split;
    deep_ois::AndroidOisLog fold_log = log;
    auto train = recording(fold_log, train_from, train_to, "train");
    auto test = recording(fold_log, test_from, test_to, "held out");
    try {
      deep_ois::StabiliserFitResult fit;
      if (fit_time_offset) {
        // The training time's own timing check moves the lens log onto the gyro (a lens that
        // fits best 2 ms ahead of the gyro gets 2 ms added), then everything is fitted again.
        auto moved_log = [&](double moved_s) {
          deep_ois::AndroidOisLog moved = log;
          for (LoggedLensSample& sample : moved.lens) sample.stamp_s += moved_s;
          return moved;
        };
        const deep_ois::LensLogTimeFit timed = deep_ois::fitStabiliserAndLensLogTime(
            [&](double moved_s) {
              return std::vector<deep_ois::StabiliserFitRecording>{
                  recording(moved_log(moved_s), train_from, train_to, "train")};
            },
            fit_options);
        fit = timed.fit;
        if (timed.moved_s != 0.0) {
          fold_log = moved_log(timed.moved_s);
          std::printf("| | lens log moved by %+.1f ms (this fold's training time's timing check) | | | | |\n",
                      1e3 * timed.moved_s);
          train = recording(fold_log, train_from, train_to, "train");
          test = recording(fold_log, test_from, test_to, "held out");
        }
      } else {
        fit = deep_ois::fitStabiliser({train}, fit_options);
      }
      // Every candidate fitted on the whole training time, scored on the held-out time (the table).
      const deep_ois::StabiliserSelection selection =
          deep_ois::selectStabiliser(fit, {train}, {test}, fit_options, {}, kinds);
      for (const auto& c : selection.candidates) {
        const RSquared r = scoreFold(c.parameters, test, fold_log, test_from, test_to, fit_options.warm_up_s);
        std::printf("| %s | %s | %.3f | %.3f | %.4f | %.4f |\n",
                    fold == 1 ? "train first, score rest" : "train rest, score first",
                    c.name.c_str(), c.training.rms_px, c.held_out.rms_px, r.motion, r.position);
      }
      // Which candidate to keep is decided on the training time alone, as train_stabiliser does
      // without --held-out recordings: fitted on its first three quarters and compared on its
      // last quarter. Choosing on the held-out time would tune the reported figure on itself.
      const double train_end = std::min(train_to, t_end);
      const double choice_from = train_from + 0.75 * (train_end - train_from);
      const auto choice_train = recording(fold_log, train_from, choice_from, "training, first three quarters");
      const auto choice_check = recording(fold_log, choice_from, train_to, "training, last quarter");
      const deep_ois::StabiliserSelection choice = deep_ois::selectStabiliser(
          deep_ois::fitStabiliser({choice_train}, fit_options), {choice_train}, {choice_check}, fit_options, {},
          kinds);
      const std::string& chosen = choice.candidates[choice.kept].name;
      std::size_t kept_index = selection.candidates.size();
      for (std::size_t i = 0; i < selection.candidates.size(); ++i)
        if (selection.candidates[i].name == chosen) kept_index = i;
      if (kept_index == selection.candidates.size())
        throw std::runtime_error("the candidate chosen on the training time ('" + chosen +
                                 "') was not built by the fit on the whole training time");
      const RSquared kept_r = scoreFold(selection.candidates[kept_index].parameters, test, fold_log,
                                        test_from, test_to, fit_options.warm_up_s);
      std::printf("| | chosen on the training time (fitted on its first three quarters, compared on its last): %s; "
                  "its held-out R^2: motion %.4f, position %.4f | | | | |\n",
                  choice.reason.c_str(), kept_r.motion, kept_r.position);
      // The fit's timing check, on this fold's training time only: where the lens motion fits
      // best against the gyro (a lens log leading it shows as a negative lag).
      if (std::isfinite(fit.review.best_lens_lag_ms))
        std::printf("| | timing check (training time only): the lens motion fits best %.1f ms %s the gyro%s | | | | |\n",
                    std::abs(fit.review.best_lens_lag_ms),
                    fit.review.best_lens_lag_ms >= 0.0 ? "behind" : "ahead of",
                    lens_time_offset_s != 0.0 || fit_time_offset ? " (after the lens log was moved)" : "");
      const auto& kept = selection.candidates[kept_index].parameters;
      if (!plots.empty())
        writeTrajectory(kept, fold_log, test_from, std::min(test_to, t_end),
                        plots + "_fold" + std::to_string(fold),
                        "lens_log_fit fold " + std::to_string(fold) + ": held-out time");
      if (fold == 1 && !out_path.empty()) {
        deep_ois::StabiliserModelFile model;
        model.parameters = kept;
        model.name = "phone lens log " + folder;
        model.training.target = "the camera's lens-shift log";
        model.training.data_files = {folder};
        model.training.recordings = 1;
        model.training.observations = fit.observations_used;
        model.training.rms_without_model_px = fit.rms_without_model_px;
        model.training.rms_px = selection.candidates[kept_index].training.rms_px;
        model.save(out_path);
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lens_log_fit: fold %d: %s\n", fold, e.what());
      status = 1;
    }
  }
  return status;
}
