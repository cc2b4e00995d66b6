#include "deep_ois/core/ois/lens_log_time_fit.h"

#include <cmath>
#include <sstream>

namespace deep_ois {

LensLogTimeFit fitStabiliserAndLensLogTime(
    const std::function<std::vector<StabiliserFitRecording>(double moved_s)>& recordings_moved_by,
    const StabiliserFitOptions& options, const ProgressCallback& progress) {
  LensLogTimeFit result;
  result.fit = fitStabiliser(recordings_moved_by(0.0), options, progress);
  result.lag_before_ms = result.fit.review.best_lens_lag_ms;
  if (!std::isfinite(result.lag_before_ms)) return result;
  // A lens that fits best ahead of the gyro (a negative lag) is moved later by as much.
  result.moved_s = -1e-3 * result.lag_before_ms;
  result.fit = fitStabiliser(recordings_moved_by(result.moved_s), options, progress);
  return result;
}

std::vector<StabiliserFitRecording> withLensLogMoved(const std::vector<StabiliserFitRecording>& recordings,
                                                     double moved_s) {
  std::vector<StabiliserFitRecording> moved = recordings;
  for (StabiliserFitRecording& recording : moved) {
    for (LensMotionObservation& o : recording.observations) {
      o.t_a_s += moved_s;
      o.t_b_s += moved_s;
    }
  }
  return moved;
}

std::string lensShiftTimeOffsetAdvice(double config_offset_s, double moved_s) {
  std::ostringstream out;
  out.precision(6);
  out << "lens_shift_time_offset: " << config_offset_s + moved_s << " (the gyro config's "
      << config_offset_s << " s";
  out.setf(std::ios::fixed);
  out.precision(1);
  out << ", plus the " << std::showpos << 1e3 * moved_s << std::noshowpos
      << " ms the lens log was moved; camera time = logged stamp + lens_shift_time_offset)";
  return out.str();
}

}  // namespace deep_ois
