// Which stabiliser model to use: the candidates (a fresh fit, the model found before for this
// camera, the shipped generic one, and always "no lens motion") scored on held-out lens motions,
// and the incumbent kept unless a candidate is clearly better there.
//
// Why "no lens motion" is always a candidate: a camera without OIS, or with OIS off, has a lens
// that does not move, and a fit on its images still finds a "lens" (it absorbs the calibration's
// and the tracker's errors; on the OIS-off CC9 a fit cancelled 79-97 % of the rotation and made the
// output 2.7 times worse than the plain gyro). Scored on data it was not fitted to, such a fit
// loses to the model that predicts no motion. The same rule serves train_stabiliser and the live
// pipeline's online learner. Pure C++/Eigen: no ROS.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_candidates.h"
#include "deep_ois/core/ois/stabiliser_choice_rule.h"
#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

bool isNoLensMotion(const StabiliserModel& parameters);

// Candidates are scored with scoreStabiliser (core/ois/stabiliser_fit.h): the RMS of
// |predicted - observed| lens motion over the observations the model can predict.

// Splits each recording in time: its observations ending in the last `held_out_fraction` of its
// observed span go to held_out (with the whole gyro stream, for the warm-up), the others to
// training. Recordings without observations are left out.
void splitRecordingsInTime(const std::vector<StabiliserFitRecording>& recordings,
                           double held_out_fraction, std::vector<StabiliserFitRecording>* training,
                           std::vector<StabiliserFitRecording>* held_out);

struct StabiliserChoice {
  std::size_t chosen = 0;            // index into the candidates
  bool replaced_incumbent = false;   // chosen != incumbent
  std::vector<StabiliserScore> scores;  // per candidate
  std::string reason;                // one sentence: the scores and why this one
};

// Scores every candidate on `held_out` and applies the choice rule (stabiliser_choice_rule.h; each
// candidate ranked by stabiliserComplexity): the simplest within the margin of the lowest RMS, "no
// lens motion" unless that is clearly better, and `incumbent` (kNoIncumbent: none) unless that is
// clearly better than it. With nothing to score (no held-out observation) the incumbent stays.
// Throws std::invalid_argument for an empty candidate list or an incumbent out of range.
StabiliserChoice chooseStabiliserModel(const std::vector<ModelCandidate>& candidates,
                                       std::size_t incumbent,
                                       const std::vector<StabiliserFitRecording>& held_out,
                                       const StabiliserChoiceOptions& options = {});

}  // namespace deep_ois

namespace deep_ois {

// train_stabiliser's check of a fit against "no lens motion": on the held-out recordings when
// there are some, else on the last quarter of each training recording with a second fit on the
// first three quarters (the fit must predict lens motion it was not fitted to). Refused when it is
// not clearly better there (the choice's margins): the camera's lens does not move as far as its
// images can tell (no OIS, OIS off, or a ground truth that only holds calibration errors).
struct NoLensMotionCheck {
  bool refused = false;
  std::string reason;  // the scores and the verdict, one sentence
  std::string scored_on;  // "the held-out recordings" or "the last quarter of each training recording ..."
  // Held-out lens-motion RMS there, pixels (NaN when nothing was scored).
  double fit_rms_px = std::numeric_limits<double>::quiet_NaN();
  double no_lens_motion_rms_px = std::numeric_limits<double>::quiet_NaN();
};
NoLensMotionCheck checkFitAgainstNoLensMotion(const StabiliserModel& fitted,
                                              const std::vector<StabiliserFitRecording>& training,
                                              const std::vector<StabiliserFitRecording>& held_out,
                                              const StabiliserFitOptions& fit_options,
                                              const StabiliserChoiceOptions& choice_options = {});

}  // namespace deep_ois
