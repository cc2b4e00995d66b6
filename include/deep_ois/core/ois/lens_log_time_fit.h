// A lens log's clock fitted against the gyro. A camera's lens-shift log (docs/lens_shift_logs.md)
// has no images to calibrate its clock against, so the stabiliser fit's own timing check
// (StabiliserFitReview::best_lens_lag_ms) is what measures it: the log is moved by what the check
// finds on the training data and the model is fitted again. lens_log_fit --fit-time-offset and
// train_stabiliser --target log --fit-time-offset share it.
//
// Sign: a log that fits best 2.6 ms ahead of the gyro (best_lens_lag_ms = -2.6) is moved by
// +2.6 ms, i.e. +0.0026 s added to the gyro config's lens_shift_time_offset (camera time = logged
// stamp + lens_shift_time_offset). Pure C++/Eigen: no ROS.
#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

struct LensLogTimeFit {
  // The fit on the log moved by moved_s (the first fit when the log was not moved).
  StabiliserFitResult fit;
  double moved_s = 0.0;  // seconds added to the log's stamps; 0 when the check measured nothing
  // The first fit's timing check (NaN when it did not run: a lens that hardly follows the rotation).
  double lag_before_ms = std::numeric_limits<double>::quiet_NaN();
};

// `recordings_moved_by(moved_s)` gives the training recordings with the lens log moved by moved_s
// seconds (0 for the log as given). Fits on the log as given, moves it by the timing check's
// finding and fits again. Throws as fitStabiliser.
LensLogTimeFit fitStabiliserAndLensLogTime(
    const std::function<std::vector<StabiliserFitRecording>(double moved_s)>& recordings_moved_by,
    const StabiliserFitOptions& options, const ProgressCallback& progress = {});

// The recordings' lens motions as observed on a log moved by `moved_s` seconds: each observation
// (the motion between two logged positions) at times later by moved_s. For lens motions that were
// read from a log at fixed row times, the same motion placed where the moved log puts it.
std::vector<StabiliserFitRecording> withLensLogMoved(const std::vector<StabiliserFitRecording>& recordings,
                                                     double moved_s);

// What to set, for a report: "lens_shift_time_offset: 0.0026 (the gyro config's 0 s, plus the
// +2.6 ms the lens log was moved; camera time = logged stamp + lens_shift_time_offset)".
std::string lensShiftTimeOffsetAdvice(double config_offset_s, double moved_s);

}  // namespace deep_ois
