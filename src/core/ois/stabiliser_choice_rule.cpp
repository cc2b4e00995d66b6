#include "deep_ois/core/ois/stabiliser_choice_rule.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace deep_ois {

bool clearlyBetter(double score, double reference, const StabiliserChoiceOptions& options) {
  return score < std::min(reference * (1.0 - options.min_relative_improvement),
                          reference - options.min_improvement_px);
}

StabiliserRuling applyStabiliserChoiceRule(const std::vector<RankedScore>& scores, std::size_t incumbent,
                                           const StabiliserChoiceOptions& options) {
  if (scores.empty()) throw std::invalid_argument("stabiliser choice: no candidate");
  if (incumbent != kNoIncumbent && incumbent >= scores.size())
    throw std::invalid_argument("stabiliser choice: incumbent " + std::to_string(incumbent) + " of " +
                                std::to_string(scores.size()) + " candidates");
  auto rms = [&](std::size_t k) {
    return std::isfinite(scores[k].rms_px) ? scores[k].rms_px : std::numeric_limits<double>::infinity();
  };
  StabiliserRuling ruling;
  const std::size_t fallback = incumbent == kNoIncumbent ? 0 : incumbent;
  ruling.chosen = ruling.lowest = fallback;
  for (std::size_t k = 0; k < scores.size(); ++k)
    if (rms(k) < rms(ruling.lowest)) ruling.lowest = k;
  if (!std::isfinite(rms(ruling.lowest)) ||
      (incumbent != kNoIncumbent && !std::isfinite(rms(incumbent)))) {
    ruling.why = StabiliserRuling::Why::kNothingScored;
    return ruling;
  }
  // 1. The simplest within the margin of the lowest (ties: the lower RMS, then the first).
  std::size_t chosen = ruling.lowest;
  for (std::size_t k = 0; k < scores.size(); ++k) {
    if (!(rms(k) <= (1.0 + options.simpler_within) * rms(ruling.lowest))) continue;
    if (scores[k].complexity < scores[chosen].complexity ||
        (scores[k].complexity == scores[chosen].complexity && rms(k) < rms(chosen)))
      chosen = k;
  }
  ruling.why = chosen == ruling.lowest ? StabiliserRuling::Why::kLowest
                                       : StabiliserRuling::Why::kSimplerWithin;
  // 2. "No lens motion" unless the choice is clearly better than it.
  for (std::size_t k = 0; k < scores.size(); ++k) {
    if (k != chosen && scores[k].no_lens_motion && std::isfinite(rms(k)) &&
        !clearlyBetter(rms(chosen), rms(k), options)) {
      ruling.passed_over = chosen;
      ruling.why = StabiliserRuling::Why::kNoLensMotion;
      chosen = k;
      break;
    }
  }
  // 3. The incumbent unless the choice is clearly better than it.
  if (incumbent != kNoIncumbent && chosen != incumbent) {
    if (clearlyBetter(rms(chosen), rms(incumbent), options)) {
      ruling.why = StabiliserRuling::Why::kReplacesIncumbent;
      ruling.replaced_incumbent = true;
    } else {
      ruling.passed_over = chosen;
      ruling.why = StabiliserRuling::Why::kIncumbentKept;
      chosen = incumbent;
    }
  }
  ruling.chosen = chosen;
  return ruling;
}

}  // namespace deep_ois
