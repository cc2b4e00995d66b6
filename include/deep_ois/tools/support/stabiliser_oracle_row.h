// The table row of a stabiliser design's oracle (core/sim/stabiliser_oracle.h): per recording, the
// design's own simulator controller and lens loop run over the recording's gyro (the camera's IMU,
// turned into the camera frame by the gyro flow's imu_to_camera_rotation, as the stabiliser model
// rows feed it), and each OIS pair compensated with the same geometry as those rows:
// K(s_b) R K(s_a)^-1 per row patch at the patches' capture times (core/ois/lens_shift_homographies.h).
// It is the bar a learned model of that design is measured against when the design's own gyro
// noise makes the whole OIS gap unreachable from the camera's gyro.
#pragma once

#include <string>

#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/sim/simulator_config.h"

namespace deep_ois {

// `design`: the simulator config of the design (its ois section is run; its sensor must be the
// recording's camera: a recording of another size is a failed pair saying so).
// `start_before_first_frame_s`: the design's stabiliser starts, centred and at rest, this long
// before the recording's first scored frame, the gyro held at its first sample until it has one;
// NaN: at the recording's first gyro sample (as the stabiliser model rows start).
// A method over OIS camera pairs; a pair the gyro does not cover is a failure with the reason
// (scored as identity and counted by the evaluator).
AlignmentMethod stabiliserOracleMethod(const std::string& name, const sim::SimulatorConfig& design,
                                       double start_before_first_frame_s,
                                       unsigned scope = kOisCameraPairs);

}  // namespace deep_ois
