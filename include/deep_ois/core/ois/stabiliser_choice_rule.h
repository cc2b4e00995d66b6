// The one rule that chooses a camera's stabiliser model among scored candidates, for
// train_stabiliser (selectStabiliser, stabiliser_candidates.h), its check against "no lens motion"
// and the live pipeline's online learner (chooseStabiliserModel, stabiliser_model_choice.h). The
// margins are in one options struct. Pure C++: no Eigen, no ROS.
//
// The rule, on each candidate's lens-motion RMS (held out where there is held-out data):
//  1. the simplest candidate within `simpler_within` of the lowest RMS is chosen (a more complex
//     model must earn its parameters);
//  2. "no lens motion" (the plain gyro), when it is a candidate, is chosen instead unless the
//     choice is clearly better than it (a fit on an OIS-off camera's noise is not);
//  3. the incumbent (the model in use), when there is one, stays unless the choice is clearly
//     better than it (the held-out window is small and noisy: a swap must pay).
// "Clearly better": below the reference's RMS by min_relative_improvement and by
// min_improvement_px.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace deep_ois {

struct StabiliserChoiceOptions {
  // Rule 1: a simpler candidate whose RMS is within this fraction of the lowest is kept instead.
  double simpler_within = 0.01;
  // Rules 2 and 3: the choice must be below the reference's RMS by this fraction ...
  double min_relative_improvement = 0.05;
  // ... and by at least this much, pixels (below the tracker's noise nothing is measured).
  double min_improvement_px = 0.005;
  // How chooseStabiliserModel runs the candidates over the held-out recordings.
  double step_s = 1e-3;
  double warm_up_s = 1.0;
};

// What the rule knows of a candidate.
struct RankedScore {
  double rms_px = std::numeric_limits<double>::quiet_NaN();  // NaN or infinite: not scored
  // Simplest first (stabiliserComplexity, stabiliser_candidates.h): 0 is "no lens motion".
  int complexity = 0;
  bool no_lens_motion = false;
};

constexpr std::size_t kNoIncumbent = std::numeric_limits<std::size_t>::max();

struct StabiliserRuling {
  std::size_t chosen = 0;
  std::size_t lowest = 0;  // the candidate with the lowest RMS (rule 1's reference)
  // Which rule decided: the lowest RMS, a simpler one within the margin, "no lens motion" as the
  // choice was not clearly better, the incumbent as the choice was not clearly better, the
  // choice replacing the incumbent, or nothing scored (the incumbent, or the first, stays).
  enum class Why { kLowest, kSimplerWithin, kNoLensMotion, kIncumbentKept, kReplacesIncumbent, kNothingScored };
  Why why = Why::kLowest;
  bool replaced_incumbent = false;  // chosen != incumbent (an incumbent given)
  std::size_t passed_over = 0;      // kNoLensMotion, kIncumbentKept: the candidate not taken
};

// Applies the rule. `incumbent` is kNoIncumbent or an index into `scores`. Throws
// std::invalid_argument for no candidate or an incumbent out of range.
StabiliserRuling applyStabiliserChoiceRule(const std::vector<RankedScore>& scores, std::size_t incumbent,
                                           const StabiliserChoiceOptions& options);

// `score` is below `reference` by both of the options' margins.
bool clearlyBetter(double score, double reference, const StabiliserChoiceOptions& options);

}  // namespace deep_ois
