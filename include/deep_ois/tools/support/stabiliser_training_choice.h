// What train_stabiliser keeps, by its final rule, and how its report says so:
//  1. the candidates (core/ois/stabiliser_candidates.h) scored, the best kept by selectStabiliser
//     (or the one --candidate names);
//  2. that candidate against "no lens motion" on data it was not fitted to
//     (checkFitAgainstNoLensMotion): when it is not clearly better there, the model written is no
//     lens motion (the plain gyro), whatever step 1 chose.
// The report names the model written and the figures that decided it, never step 1's pick alone.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_model_choice.h"

namespace deep_ois {

struct StabiliserTrainingChoice {
  StabiliserSelection selection;  // every candidate scored (held_out.observations 0 without --held-out)
  std::size_t candidate = 0;      // the candidate checked against no lens motion
  bool forced = false;            // --candidate chose it, not selectStabiliser
  NoLensMotionCheck lens_check;

  bool keptNoLensMotion() const { return lens_check.refused; }
  std::string keptName() const;                // "no lens motion" or the candidate's name
  StabiliserModel keptParameters() const;  // noLensMotion() or the candidate's
  // The kept model's training RMS, pixels (for no lens motion: the lens motion itself).
  double keptTrainingRmsPx() const;
  bool hasHeldOut() const;  // the candidates were scored on held-out recordings
};

// Steps 1 and 2 above. `forced_candidate`: keep the candidate whose name contains it instead of
// the best (empty: the best); throws std::invalid_argument naming it when none does.
StabiliserTrainingChoice chooseTrainedStabiliser(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const std::vector<StabiliserFitRecording>& held_out,
                                                 const StabiliserFitOptions& options,
                                                 const std::string& forced_candidate = "",
                                                 const StabiliserCandidateKinds& kinds = {});

// One paragraph: the model written and why, with the figures that decided it ("kept 'no lens
// motion' (the plain gyro): the best candidate, 'physical', does not predict the lens motion
// better than no lens motion on ...: 0.412 px against 0.398 px ...").
std::string keptModelReason(const StabiliserTrainingChoice& choice);

// The candidates' lens-motion RMS (training, held out) as a markdown table, "no lens motion" as
// the last row, the model written marked "kept"; a figure that was not computed is "n/a", with a
// line under the table saying why.
std::string candidateTable(const StabiliserTrainingChoice& choice);

}  // namespace deep_ois
