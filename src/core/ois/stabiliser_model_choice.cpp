#include "deep_ois/core/ois/stabiliser_model_choice.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/ois/stabiliser_choice_rule.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"

namespace deep_ois {

bool isNoLensMotion(const StabiliserModel& parameters) {
  auto zero = [](const Eigen::MatrixXd& m) { return m.size() == 0 || m.isZero(0.0); };
  const CentringValues* centring = parameters.find<CentringValues>();
  const LinearDynamicsValues* linear = parameters.find<LinearDynamicsValues>();
  return centring && centring->gain.isZero(0.0) && (!linear || zero(linear->coefficients));
}

void splitRecordingsInTime(const std::vector<StabiliserFitRecording>& recordings,
                           double held_out_fraction, std::vector<StabiliserFitRecording>* training,
                           std::vector<StabiliserFitRecording>* held_out) {
  for (const auto& recording : recordings) {
    if (recording.observations.empty()) continue;
    double first = recording.observations.front().t_b_s, last = first;
    for (const auto& o : recording.observations) {
      first = std::min(first, o.t_b_s);
      last = std::max(last, o.t_b_s);
    }
    const double split = last - held_out_fraction * (last - first);
    StabiliserFitRecording early = recording, late = recording;
    early.observations.clear();
    late.observations.clear();
    late.name += " (held-out end)";
    for (const auto& o : recording.observations) (o.t_b_s > split ? late : early).observations.push_back(o);
    if (!early.observations.empty()) training->push_back(std::move(early));
    if (!late.observations.empty()) held_out->push_back(std::move(late));
  }
}

StabiliserChoice chooseStabiliserModel(const std::vector<ModelCandidate>& candidates,
                                       std::size_t incumbent,
                                       const std::vector<StabiliserFitRecording>& held_out,
                                       const StabiliserChoiceOptions& options) {
  if (candidates.empty()) throw std::invalid_argument("chooseStabiliserModel: no candidate");
  if (incumbent != kNoIncumbent && incumbent >= candidates.size())
    throw std::invalid_argument("chooseStabiliserModel: incumbent " + std::to_string(incumbent) +
                                " of " + std::to_string(candidates.size()) + " candidates");
  StabiliserChoice choice;
  StabiliserFitOptions scoring;
  scoring.step_s = options.step_s;
  scoring.warm_up_s = options.warm_up_s;
  std::vector<RankedScore> ranked;
  for (const auto& candidate : candidates) {
    choice.scores.push_back(scoreStabiliser(candidate.parameters, held_out, scoring));
    RankedScore score;
    score.rms_px = choice.scores.back().observations > 0 ? choice.scores.back().rms_px
                                                         : std::numeric_limits<double>::quiet_NaN();
    score.complexity = stabiliserComplexity(candidate.parameters);
    score.no_lens_motion = isNoLensMotion(candidate.parameters);
    ranked.push_back(score);
  }
  const StabiliserRuling ruling = applyStabiliserChoiceRule(ranked, incumbent, options);
  choice.chosen = ruling.chosen;
  choice.replaced_incumbent = ruling.replaced_incumbent;
  std::ostringstream why;
  why.precision(3);
  why << "held-out lens motion RMS:";
  for (std::size_t c = 0; c < candidates.size(); ++c)
    why << (c ? "," : "") << " " << candidates[c].name << " " << std::fixed << choice.scores[c].rms_px << " px";
  const std::string& chosen = candidates[ruling.chosen].name;
  using Why = StabiliserRuling::Why;
  switch (ruling.why) {
    case Why::kNothingScored:
      why << "; nothing held out to score: " << chosen << " kept";
      break;
    case Why::kReplacesIncumbent:
      why << "; " << chosen << " replaces " << candidates[incumbent].name;
      break;
    case Why::kIncumbentKept:
    case Why::kNoLensMotion:
      why << "; " << chosen << " kept: " << candidates[ruling.passed_over].name << " is not better by "
          << 100.0 * options.min_relative_improvement << " % and " << options.min_improvement_px << " px";
      break;
    case Why::kSimplerWithin:
      why << "; " << chosen << " kept: within " << 100.0 * options.simpler_within << " % of the best ("
          << candidates[ruling.lowest].name << ") and simpler";
      break;
    case Why::kLowest:
      why << "; " << chosen << " kept (the best)";
      break;
  }
  choice.reason = why.str();
  return choice;
}

}  // namespace deep_ois

namespace deep_ois {

NoLensMotionCheck checkFitAgainstNoLensMotion(const StabiliserModel& fitted,
                                              const std::vector<StabiliserFitRecording>& training,
                                              const std::vector<StabiliserFitRecording>& held_out,
                                              const StabiliserFitOptions& fit_options,
                                              const StabiliserChoiceOptions& choice_options) {
  StabiliserChoiceOptions options = choice_options;
  options.step_s = fit_options.step_s;
  options.warm_up_s = fit_options.warm_up_s;
  NoLensMotionCheck check;
  StabiliserModel candidate = fitted;
  std::vector<StabiliserFitRecording> scored = held_out;
  std::string where = "the held-out recordings";
  if (held_out.empty()) {
    std::vector<StabiliserFitRecording> early;
    splitRecordingsInTime(training, 0.25, &early, &scored);
    where = "the last quarter of each training recording (fitted again on the first three quarters)";
    try {
      candidate = fitStabiliser(early, fit_options).parameters;
    } catch (const std::exception& e) {
      check.refused = true;
      check.reason = std::string("the fit on the first three quarters failed (") + e.what() +
                     "): nothing shows that the lens moves";
      check.scored_on = where;
      return check;
    }
  }
  const StabiliserChoice choice =
      chooseStabiliserModel({{"fit", candidate}, {"no lens motion", noLensMotion()}}, 1, scored, options);
  check.refused = !choice.replaced_incumbent;
  check.reason = "on " + where + ": " + choice.reason;
  check.scored_on = where;
  check.fit_rms_px = choice.scores[0].rms_px;
  check.no_lens_motion_rms_px = choice.scores[1].rms_px;
  return check;
}

}  // namespace deep_ois
