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
  Eigen::Vector3d shake_rms_rad_s{0.2, 0.2, 0.07};  // RMS rate about camera x, y, z, rad/s
  // Bound on |shake| (the norm of the shake part of the rate), rad/s: a smooth limiter scales the
  // shake down where it would exceed this. |w| <= shake_peak_rad_s + pan_peak_rad_s overall.
  double shake_peak_rad_s = 0.5;
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
// dR/dt = R [w_cam(t)]x exactly up to the internal integration step (4 kHz, fourth order), so a
// gyro sampling angularVelocity() reproduces pose() to far below a pixel. The pose at t = 0 (or
// at start_s / end_s when 0 is outside the span) is the reference: centre at the world origin,
// looking along world +x with image rows horizontal.
class CameraMotion {
 public:
  // Throws std::invalid_argument with the validate() sentence, or for a bad time span.
  CameraMotion(const CameraMotionConfig& config, std::uint32_t seed, double start_s, double end_s);

  CameraPose pose(double t_s) const;  // interpolated on the internal grid; held outside the span
  Eigen::Vector3d angularVelocity(double t_s) const;     // camera frame, rad/s (closed form)
  Eigen::Vector3d linearAcceleration(double t_s) const;  // of the centre, world frame, m/s^2
  double startTime() const { return start_s_; }
  double endTime() const { return end_s_; }

 private:
  struct Sinusoid {
    double amplitude;  // rad/s (rotation) or m (translation)
    double frequency_hz;
    double phase_rad;
  };
  Eigen::Vector3d unlimitedShake(double t_s) const;  // rad/s, camera frame
  Eigen::Vector3d panRate(double t_s) const;         // rad/s, camera frame
  Eigen::Vector3d translationSeries(double t_s) const;
  void integrateOrientation();

  CameraMotionConfig config_;
  double start_s_, end_s_;
  std::vector<Sinusoid> shake_[3];        // angular velocity per camera axis, rad/s
  std::vector<Eigen::Vector2d> pans_;     // peak pan rate about camera x, y per pan period, rad/s
  std::vector<Sinusoid> translation_[3];  // centre per world axis, m
  Eigen::Vector3d centre_anchor_m_ = Eigen::Vector3d::Zero();  // series at the anchor time
  // Orientation grid at integration_rate_hz from start_s_: R_world_cam, the body rate there and
  // the body-frame rotation vector of each step (k -> k+1), for cubic interpolation in between.
  double grid_step_s_ = 0.0;
  std::vector<Eigen::Vector4d> orientation_grid_;  // Eigen::Quaterniond coefficients (x, y, z, w)
  std::vector<Eigen::Vector3d> rate_grid_;
  std::vector<Eigen::Vector3d> step_rotation_grid_;
};

}  // namespace sim
}  // namespace deep_ois
