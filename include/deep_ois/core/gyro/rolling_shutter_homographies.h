// Per-row-patch rotation homographies between two rolling-shutter frames, from the gyroscope.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/orientation_integrator.h"

namespace deep_ois {

// Which row of a patch stands for the whole patch when its capture time is computed.
enum class PatchTimeReference {
  kPatchStart,   // first row, t = stamp + readout * i / N (the paper's and authors' choice)
  kPatchCentre,  // middle row, t = stamp + readout * (i + 0.5) / N (halves the worst row error)
};

struct RollingShutterConfig {
  int patch_count = 6;          // N row patches; patch i holds rows [i*h/N, (i+1)*h/N)
  double readout_time_s = 0.0;  // first row to last row; 0 = global shutter
  double time_offset_s = 0.0;   // added to camera stamps to get IMU time
  PatchTimeReference patch_time = PatchTimeReference::kPatchCentre;
  // R_cam_imu: a vector in the IMU frame is R_cam_imu * v in the camera optical frame.
  Eigen::Matrix3d imu_to_camera_rotation = Eigen::Matrix3d::Identity();

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// IMU-clock time (seconds) at which patch `patch_index` of a frame stamped `frame_stamp_s`
// (camera clock, start of readout of the first row) is captured.
double patchImuTime(const RollingShutterConfig& config, double frame_stamp_s, int patch_index);

// The IMU interval a frame pair needs: from patch 0 of frame a to the last patch of frame b.
struct ImuInterval {
  double begin_s;
  double end_s;
};
ImuInterval requiredImuInterval(const RollingShutterConfig& config, double stamp_a_s,
                                double stamp_b_s);

// Patch index of (possibly fractional) raw image row `row_px`, clamped to [0, N-1].
int patchIndexOfRow(double row_px, int image_height_px, int patch_count);

// K R K^-1 with H[2][2] = 1: the homography of a pure rotation R of the camera frame, R mapping
// points of frame a's camera frame to frame b's.
Eigen::Matrix3d rotationHomography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& R_b_a);

struct RollingShutterHomographies {
  IntegrationStatus status = IntegrationStatus::kOk;
  std::string reason;  // empty when ok
  // H_i maps undistorted pixels of frame a in patch i to frame b; H[2][2] = 1.
  std::vector<Eigen::Matrix3d> homographies;
  // R_b_a per patch: rotation from frame a's camera frame to frame b's at that patch's rows.
  std::vector<Eigen::Matrix3d> rotations;
  bool ok() const { return status == IntegrationStatus::kOk; }
};

// For every patch i: integrate the gyro over [t_a(i), t_a(i) + (stamp_b - stamp_a)], express the
// rotation in the camera frame, and form H_i = K R_b_a K^-1. Stamps are camera-clock seconds.
RollingShutterHomographies computeRollingShutterHomographies(const ImuSampleBuffer& buffer,
                                                             const IntegrationOptions& integration,
                                                             const RollingShutterConfig& config,
                                                             const Eigen::Matrix3d& K,
                                                             double stamp_a_s, double stamp_b_s);

}  // namespace deep_ois
