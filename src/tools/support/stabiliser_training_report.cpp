#include "deep_ois/tools/support/stabiliser_training_report.h"

#include <algorithm>
#include <cmath>

#include "deep_ois/core/common/printf_text.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {

std::string countOf(std::size_t count, const std::string& singular, const std::string& plural) {
  return std::to_string(count) + " " + (count == 1 ? singular : plural);
}

std::string recordingSummary(const std::string& bag, const StabiliserRecordingData& data,
                             LensMotionTarget target, bool cached) {
  std::string line = bag + ": " + countOf(data.frame_pairs, "pair", "pairs") + ", " +
                     countOf(data.recording.observations.size(), "lens motion", "lens motions");
  if (data.pairs_without_gyro > 0)
    line += ", " + countOf(data.pairs_without_gyro, "pair", "pairs") + " without gyro";
  if (data.pairs_without_tracks > 0)
    line += ", " + countOf(data.pairs_without_tracks, "pair", "pairs") +
            " with too few tracks (left out)";
  if (data.pairs_without_log > 0)
    line += ", " + countOf(data.pairs_without_log, "pair", "pairs") +
            " the lens log does not cover (left out)";
  // Only the images' estimate has tracks to leave a residual.
  if (target == LensMotionTarget::kImages)
    line += ", track residual " + printfText("%.3f", data.median_track_residual_px) + " px";
  if (cached) line += " (cached)";
  return line;
}

std::string readoutMismatch(const StabiliserRecordingData& data, double config_readout_s) {
  const double recorded = data.recorded_readout_time_s;
  if (recorded < 0.0) return "";
  const double difference = std::abs(recorded - config_readout_s);
  if (difference <= std::max(0.0005, 0.02 * recorded)) return "";
  return "readout_time: the gyro config says " + printfText("%.1f", 1000.0 * config_readout_s) +
         " ms but the recording says " + printfText("%.1f", 1000.0 * recorded) +
         " ms (its simulator truth): the lens motions and the model are computed with the wrong "
         "readout; set readout_time: " +
         printfText("%g", recorded) + " in the gyro config";
}

std::string stabiliserParameterTable(const StabiliserModel& model,
                                     const StabiliserFitReview& review) {
  auto bound = [&](const char* parameter) {
    return review.onBound(parameter) ? std::string(" (on the fit's bound)") : std::string();
  };
  // The chain's stages (a model the fit made has them all).
  const CentringValues& centring = model.get<CentringValues>();
  const ActuatorValues& actuator = model.get<ActuatorValues>();
  const StrokeValues& stroke = model.get<StrokeValues>();
  const PanDetectionValues& pan = model.get<PanDetectionValues>();
  const ExcursionCentringValues* excursion = model.find<ExcursionCentringValues>();
  const LinearDynamicsValues* linear = model.find<LinearDynamicsValues>();
  const Eigen::Matrix2d& gain = centring.gain;
  std::string out = "| parameter | value |\n|---|---|\n";
  out += printfText("| gain | [%.3f %.3f; %.3f %.3f] |\n", gain(0, 0), gain(0, 1), gain(1, 0), gain(1, 1));
  out += "| centring corner | " + printfText("%.3f", centring.highpass_corner_hz) + " Hz" +
         bound("highpass_corner_hz") + " |\n";
  out += "| actuator | " + printfText("%.1f", actuator.actuator_natural_hz) + " Hz" +
         bound("actuator_natural_hz") + ", damping " + printfText("%.2f", actuator.actuator_damping) +
         bound("actuator_damping") + " |\n";
  out += "| sensor lag | " + printfText("%.2f", 1000.0 * actuator.sensor_lag_s) + " ms" +
         bound("sensor_lag_s") + " |\n";
  out += "| stroke | " + printfText("%.3f", stroke.stroke_x_deg) + bound("stroke_x_deg") + " x " +
         printfText("%.3f", stroke.stroke_y_deg) + bound("stroke_y_deg") + " deg (" +
         (stroke.circular_stroke ? "ellipse" : "box") +
         (stroke.soft_stroke ? ", soft: stroke x tanh(u / stroke)" : "") + ") |\n";
  out += std::string("| integrator at the stroke | ") +
         (stroke.anti_windup ? "held (anti-windup)" : "winds up") + " |\n";
  if (excursion && excursion->excursion_centring > 0.0)
    out += "| excursion-dependent re-centring | corner x (1 + " +
           printfText("%.2f", excursion->excursion_centring) + " e^2) |\n";
  out += "| pan detection | " +
         (pan.pan_detection_rate_rad_s > 0.0
              ? printfText("%.2f", pan.pan_detection_rate_rad_s) + " rad/s, release " +
                    printfText("%.2f", pan.pan_release_corner_hz) + " Hz" + bound("pan_release_corner_hz")
              : std::string("off")) +
         " |\n";
  if (linear && linear->active())
    out += "| linear dynamics | " + countOf(static_cast<std::size_t>(linear->basis.order), "function", "functions") +
           " per gyro axis (" + (linear->basis.firstOrder() ? "first-order low-passes" : "Laguerre") + "), into the " +
           (linear->output_to_lens ? "lens" : "raw command") + " |\n";
  return out;
}

std::string lensMotionTable(const std::vector<LensMotionScoreRow>& rows) {
  std::string out =
      "| data | lens motions | without a lens model | with the model |\n"
      "|---|---:|---:|---:|\n";
  auto cell = [](double value) { return std::isfinite(value) ? printfText("%.3f", value) : "n/a"; };
  for (const LensMotionScoreRow& row : rows) {
    out += "| " + row.data + " (" + countOf(row.recordings, "recording", "recordings") + ") | " +
           std::to_string(row.observations) + " | " + cell(row.without_model_px) + " | " +
           cell(row.model_px) + " |\n";
  }
  return out;
}

}  // namespace deep_ois
