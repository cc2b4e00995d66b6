// The table row of a learned stabiliser model (core/ois/): per recording, one frame-pair processor
// (core/pipeline/frame_pair_processor.h) fed with the recording's gyro stream in pair order, so
// the stabiliser's state is carried across pairs exactly as the compensation nodelet carries it.
#pragma once

#include <string>

#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

// A method over OIS camera pairs; a pair the model cannot cover (no gyro stream in the context, a
// gap) is a failure with the reason, scored as identity and counted by the evaluator.
AlignmentMethod stabiliserAlignmentMethod(const std::string& name,
                                          const StabiliserModel& parameters,
                                          unsigned scope = kOisCameraPairs);

}  // namespace deep_ois
