// The simulated rolling-shutter OIS camera: its geometry at any time. The renderer and the
// ground truth both use it, so pixels and annotations follow one model.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/ois_model.h"

namespace deep_ois {
namespace sim {

struct SensorConfig {
  int width_px = 360;
  int height_px = 270;
  double horizontal_fov_deg = 70.0;
  double frame_rate_hz = 30.0;
  double readout_time_s = 0.022;  // first row to last row; 0 = global shutter
  double exposure_time_s = 0.008;
  // Lens model, as CameraInfo names it: "plumb_bob" (distortion = k1, k2, p1, p2, k3) or
  // "equidistant" (a fisheye: distortion = k1, k2, k3, k4).
  std::string distortion_model = "plumb_bob";
  // The model's coefficients (all zero: no distortion)
  std::vector<double> distortion{0.0, 0.0, 0.0, 0.0, 0.0};
  int supersampling = 2;     // samples per pixel along each axis (anti-aliasing)
  int exposure_samples = 3;  // time samples inside the exposure (motion blur)
  // Photometry: radiance * brightness is the mean fraction of full well; shot noise from
  // full_well_electrons, read noise in electrons; output is 8-bit sRGB-like (gamma 2.2).
  double brightness = 1.0;
  double full_well_electrons = 6000.0;
  double read_noise_electrons = 2.0;
  bool add_noise = true;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

// Stamps are the mid-exposure time of the first row; row r is exposed around
// stamp + readout_time * r / height (the convention of the gyro flow, so time_offset 0 is right).
class SimCamera {
 public:
  SimCamera(const SensorConfig& sensor, const CameraMotion& motion, const OisModel& ois);

  const SensorConfig& sensor() const { return sensor_; }
  // Intrinsics without OIS shift (what camera_info reports) and the distortion.
  const CameraModel& nominal() const { return nominal_; }
  const CameraMotion& motion() const { return motion_; }
  const OisModel& ois() const { return ois_; }

  double rowTime(double stamp_s, double row_px) const;  // mid-exposure time of a (fractional) row
  // K at time t: nominal K with the principal point moved by the OIS lens shift.
  Eigen::Matrix3d intrinsicsAt(double t_s) const;

  // World ray through raw (distorted) pixel `pixel` at time t: origin = camera centre.
  Eigen::Vector3d rayDirectionWorld(const Eigen::Vector2d& pixel, double t_s) const;
  // Raw pixel of world point X at time t; false when X is behind the camera.
  bool project(const Eigen::Vector3d& X_world_m, double t_s, Eigen::Vector2d* pixel) const;
  // Raw pixel of a static world point in the frame stamped `stamp_s`, with the row time solved
  // consistently (the point is seen at the time its own row is exposed). False when behind the
  // camera, outside the image, or the iteration does not settle.
  bool projectRollingShutter(const Eigen::Vector3d& X_world_m, double stamp_s,
                             Eigen::Vector2d* pixel, double* t_s = nullptr) const;

 private:
  SensorConfig sensor_;
  const CameraMotion& motion_;
  const OisModel& ois_;
  CameraModel nominal_;
};

// Nominal intrinsics of a sensor: fx = fy = (w / 2) / tan(fov / 2), principal point at the image
// centre ((w - 1) / 2, (h - 1) / 2).
CameraModel nominalCamera(const SensorConfig& sensor);

}  // namespace sim
}  // namespace deep_ois
