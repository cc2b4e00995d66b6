// The calibration as the gyro flow nodelet's parameters: a YAML file that
// loadGyroFlowParameters() reads (readout_time, time_offset, imu_to_camera_rotation, gyro_bias),
// to load after config/gyro_flow.yaml, and the equivalent static transform.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/camera_imu_calibration.h"

namespace deep_ois {

// What the file says about where the calibration came from (comments only).
struct CalibrationProvenance {
  std::string source;            // the bag or recording
  std::string imu_frame_id;      // for the static transform line
  std::string camera_frame_id;
  LensShiftHandling lens_shift = LensShiftHandling::kNone;
  // Further comment lines, e.g. which values came from the data and which from the metadata.
  std::vector<std::string> notes;
};

// The YAML text: the four parameters, with the uncertainties, diagnostics and the static
// transform as comments. Numbers are written with enough digits to read back the same doubles
// to 1e-12 relative.
std::string calibrationYaml(const CalibrationResult& result, const CalibrationProvenance& provenance);

// Writes `text` to `path` (through a temporary file renamed into place, so a failed write never
// leaves half a file). Throws std::runtime_error naming the path.
void writeTextFile(const std::string& path, const std::string& text);

// `rosrun tf2_ros static_transform_publisher 0 0 0 qx qy qz qw <imu> <camera>`: publishes the
// camera's orientation in the IMU frame (R_cam_imu^T), so tf's lookup camera <- IMU yields
// R_cam_imu, as the simulator's /tf_static does.
std::string staticTransformCommand(const Eigen::Matrix3d& imu_to_camera_rotation,
                                   const std::string& imu_frame_id, const std::string& camera_frame_id);

}  // namespace deep_ois
