// Hand-held camera motion for the OIS simulator: band-limited angular shake, slow intentional
// pans and small translation, deterministic for a seed. Pure C++/Eigen.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace deep_ois {
namespace sim {

struct CameraMotionConfig {
  // Shake: angular velocity as band-limited noise (a random-phase Fourier series over the band),
  // per camera axis. Roll (about the optical axis) is usually weaker on a hand-held phone.
  double shake_band_low_hz = 1.0;
  double shake_band_high_hz = 12.0;
  Eigen::Vector3d shake_rms_rad_s{0.15, 0.15, 0.06};  // RMS rate about camera x, y, z, rad/s
  double shake_peak_rad_s = 0.5;  // rates are scaled down where |w| would exceed this, rad/s
  // Intentional pans: smooth yaw/pitch rate changes, rad/s peak, over periods of seconds.
  double pan_peak_rad_s = 0.2;
  double pan_period_s = 4.0;
  // Translation: smooth band-limited wobble of the camera centre, metres RMS per axis.
  double translation_rms_m = 0.01;
  double translation_band_high_hz = 3.0;
  double integration_rate_hz = 4000.0;  // internal orientation integration rate

  std::string validate() const;  // empty, or a sentence naming the bad field
};

// A camera pose at one time: R_world_cam maps camera-frame (optical) vectors to the world;
// centre_world_m is the optical centre in world metres. World: z up, camera at t=0 looks along +x.
struct CameraPose {
  Eigen::Matrix3d R_world_cam = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre_world_m = Eigen::Vector3d::Zero();
};

// The motion over [start_s, end_s] (seconds, simulation clock). Orientation obeys
// dR/dt = R [w_cam(t)]x exactly up to the internal integration step (4 kHz, third order), so a
// gyro sampling angularVelocity() reproduces pose() to far below a pixel.
class CameraMotion {
 public:
  CameraMotion(const CameraMotionConfig& config, std::uint32_t seed, double start_s, double end_s);

  CameraPose pose(double t_s) const;                     // interpolated on the internal grid
  Eigen::Vector3d angularVelocity(double t_s) const;     // camera frame, rad/s (closed form)
  Eigen::Vector3d linearAcceleration(double t_s) const;  // of the centre, world frame, m/s^2
  double startTime() const { return start_s_; }
  double endTime() const { return end_s_; }

 private:
  // Implementation-defined members (Fourier components, integrated orientation grid, ...).
  struct Component {
    double frequency_hz, phase_rad;
    Eigen::Vector3d amplitude;
  };
  CameraMotionConfig config_;
  double start_s_, end_s_;
  std::vector<Component> rotation_components_;     // angular velocity, rad/s
  std::vector<Component> translation_components_;  // position, m
  double rate_scale_ = 1.0;                        // keeps |w| <= shake_peak_rad_s
  std::vector<Eigen::Vector4d> orientation_grid_;  // quaternions (w,x,y,z) at integration_rate_hz
};

}  // namespace sim
}  // namespace deep_ois
