// What train_stabiliser prints: a line per recording read, the fitted parameters and the
// lens-motion residuals per data set (markdown), kept here so that their wording is tested.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/ros/bag/stabiliser_training_data.h"

namespace deep_ois {

// "1 recording", "3 recordings".
std::string countOf(std::size_t count, const std::string& singular, const std::string& plural);

// "<bag>: 120 pairs, 714 lens motions[, ...left out][, track residual 0.123 px][ (cached)]": the
// track residual only for the images' target (a lens log or the simulator's truth has no tracks).
std::string recordingSummary(const std::string& bag, const StabiliserRecordingData& data,
                             LensMotionTarget target, bool cached);

// Empty when the recording states no readout time or the same as the gyro config's (within 2 %
// and 0.5 ms); otherwise a sentence naming readout_time and both values.
std::string readoutMismatch(const StabiliserRecordingData& data, double config_readout_s);

// The fitted parameters as a markdown table; a value that ended on a bound of the fit says so.
std::string stabiliserParameterTable(const StabiliserModel& parameters,
                                     const StabiliserFitReview& review);

// One row of the lens-motion table: RMS residual norms in pixels (NaN: not computed).
struct LensMotionScoreRow {
  std::string data;  // "training", "held out"
  std::size_t recordings = 0;
  std::size_t observations = 0;
  double without_model_px = 0.0;
  double model_px = 0.0;
};
std::string lensMotionTable(const std::vector<LensMotionScoreRow>& rows);

}  // namespace deep_ois
