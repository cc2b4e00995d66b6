#include "deep_ois/tools/support/stabiliser_training_choice.h"

#include <cmath>
#include <stdexcept>

#include "deep_ois/core/common/printf_text.h"

namespace deep_ois {

namespace {

std::string pixels(double value) {
  return std::isfinite(value) ? printfText("%.4f", value) : std::string("n/a");
}

}  // namespace

std::string StabiliserTrainingChoice::keptName() const {
  return keptNoLensMotion() ? std::string("no lens motion") : selection.candidates.at(candidate).name;
}

StabiliserModel StabiliserTrainingChoice::keptParameters() const {
  return keptNoLensMotion() ? noLensMotion() : selection.candidates.at(candidate).parameters;
}

double StabiliserTrainingChoice::keptTrainingRmsPx() const {
  const StabiliserScore& training = selection.candidates.at(candidate).training;
  return keptNoLensMotion() ? training.rms_without_model_px : training.rms_px;
}

bool StabiliserTrainingChoice::hasHeldOut() const {
  return !selection.candidates.empty() && selection.candidates.front().held_out.observations > 0;
}

StabiliserTrainingChoice chooseTrainedStabiliser(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const std::vector<StabiliserFitRecording>& held_out,
                                                 const StabiliserFitOptions& options,
                                                 const std::string& forced_candidate,
                                                 const StabiliserCandidateKinds& kinds) {
  StabiliserTrainingChoice choice;
  choice.selection = selectStabiliser(fit, training, held_out, options, {}, kinds);
  choice.candidate = choice.selection.kept;
  if (!forced_candidate.empty()) {
    const auto& candidates = choice.selection.candidates;
    std::size_t k = 0;
    while (k < candidates.size() && candidates[k].name.find(forced_candidate) == std::string::npos) ++k;
    if (k == candidates.size())
      throw std::invalid_argument("--candidate: no candidate named '" + forced_candidate + "'");
    choice.candidate = k;
    choice.forced = true;
  }
  // Without --held-out the check refits the physical chain on 3/4 of each recording.
  choice.lens_check = checkFitAgainstNoLensMotion(choice.selection.candidates[choice.candidate].parameters,
                                                  training, held_out, options);
  return choice;
}

std::string keptModelReason(const StabiliserTrainingChoice& choice) {
  const StabiliserSelection& selection = choice.selection;
  const std::string name = selection.candidates.at(choice.candidate).name;
  const std::string picked =
      choice.forced
          ? "'" + name + "', as --candidate asked (the rule would pick '" +
                selection.candidates.at(selection.kept).name + "': " + selection.figures + ")"
          : "'" + name + "' (" + selection.figures + ")";
  const NoLensMotionCheck& check = choice.lens_check;
  const std::string figures =
      std::isfinite(check.fit_rms_px)
          ? printfText("%.4f px against %.4f px for no lens motion", check.fit_rms_px,
                       check.no_lens_motion_rms_px)
          : check.reason;
  if (choice.keptNoLensMotion()) {
    const StabiliserChoiceOptions margins;
    return "kept 'no lens motion' (the plain gyro: a camera without OIS, with OIS off, or whose lens "
           "motion its data cannot show): the best candidate, " +
           picked + ", is refused: on " + check.scored_on +
           ", the fit predicts the lens motion no better than no lens motion (" + figures +
           printfText("; it must be %.0f %% and %.3f px better)", 100.0 * margins.min_relative_improvement,
                      margins.min_improvement_px);
  }
  return "kept " + picked + "; it predicts the lens motion clearly better than no lens motion on " +
         check.scored_on + " (" + figures + ")";
}

std::string candidateTable(const StabiliserTrainingChoice& choice) {
  const StabiliserSelection& selection = choice.selection;
  std::string out = "| candidate | training | held out | |\n|---|---:|---:|---|\n";
  for (std::size_t k = 0; k < selection.candidates.size(); ++k) {
    const StabiliserCandidate& c = selection.candidates[k];
    const bool kept = !choice.keptNoLensMotion() && k == choice.candidate;
    const bool checked = choice.keptNoLensMotion() && k == choice.candidate;
    out += "| " + c.name + " | " + pixels(c.training.rms_px) + " | " + pixels(c.held_out.rms_px) + " | " +
           (kept ? "kept" : checked ? "refused against no lens motion" : "") + " |\n";
  }
  if (!selection.candidates.empty()) {
    const StabiliserCandidate& first = selection.candidates.front();
    out += "| no lens motion | " + pixels(first.training.rms_without_model_px) + " | " +
           pixels(first.held_out.rms_without_model_px) + " | " + (choice.keptNoLensMotion() ? "kept" : "") +
           " |\n";
  }
  if (!choice.hasHeldOut()) {
    out += "\nheld out: n/a, no --held-out recordings: the candidates were compared on their training "
           "RMS, and the check against no lens motion on " +
           choice.lens_check.scored_on + ".\n";
  }
  return out;
}

}  // namespace deep_ois
