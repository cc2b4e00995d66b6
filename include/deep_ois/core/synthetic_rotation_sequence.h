// A deterministic synthetic hand-held camera that only rotates: gyroscope samples and
// rolling-shutter frames of a textured environment at infinity that agree exactly. Pure C++:
// Eigen + OpenCV, no ROS.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/camera_model.h"
#include "deep_ois/core/imu_sample_buffer.h"
#include "deep_ois/core/rolling_shutter_homographies.h"

namespace deep_ois {

// Every time in this file is "sequence time": seconds since the stamp of frame 0, on the camera
// clock unless said otherwise. IMU stamps are on the IMU clock = camera clock + time_offset_s.
// Callers that need absolute stamps (a bag) add their own epoch, which keeps the motion formulas
// evaluated at small times where doubles are exact to the nanosecond.
struct SyntheticSequenceConfig {
  std::uint32_t seed = 1;  // selects both the motion and the environment

  // Camera.
  int width_px = 360;
  int height_px = 270;
  double horizontal_fov_deg = 70.0;  // K: fx = fy = (w / 2) / tan(fov / 2), centre (w-1)/2, (h-1)/2
  std::vector<double> plumb_bob;     // k1 k2 p1 p2 k3 for the rendered (raw) images; empty = none
  double frame_rate_hz = 30.0;
  double duration_s = 3.0;        // frames at k / frame_rate for k = 0 .. floor(duration * rate)-1
  double readout_time_s = 0.022;  // first to last row; 0 = global shutter
  int supersampling = 2;          // n x n samples per pixel, all at the row's capture time

  // IMU.
  double imu_rate_hz = 400.0;
  // IMU samples start this long before frame 0 and end this long after the last row of the last
  // frame, so that any consumer can integrate across every frame pair.
  double imu_margin_s = 0.1;
  double time_offset_s = 0.0;         // IMU clock = camera clock + time_offset_s
  double gyro_noise_std_rad_s = 0.0;  // white noise per sample and axis; 0 = exact rates
  // R_cam_imu: a vector in the IMU frame is R_cam_imu * v in the camera optical frame. Default:
  // phone-like, IMU x = camera y, IMU y = camera x, IMU z = -camera z.
  Eigen::Matrix3d imu_to_camera_rotation = phoneImuToCamera();

  // Motion: angular velocity in the camera frame = pan + per axis a sum of sinusoids.
  int sinusoids_per_axis = 3;
  double shake_min_hz = 1.0;
  double shake_max_hz = 12.0;
  // Largest per-axis sum of shake amplitudes, rad/s (each axis draws between 60 % and 100 %).
  double shake_rate_rad_s = 0.5;
  double pan_rate_rad_s = 0.15;         // slow steady pan, mostly about camera y (yaw)
  double integration_rate_hz = 4000.0;  // orientation table steps; rows interpolate within one

  // Environment cube map: face edge in texels. The environment is a direction -> colour function
  // (value-noise background + shapes), sampled once into the cube map, which then defines it:
  // rendering and environmentColour() are one bilinear cube lookup per sample. 1024 texels per
  // 90 degrees is finer than the default camera's 2x2 sub-samples (~0.1 degree).
  int environment_face_px = 1024;
  int environment_shape_count = 700;  // coloured rectangles and discs painted on the sphere

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;

  static Eigen::Matrix3d phoneImuToCamera();
};

// The motion, IMU stream and renderer. Construction builds the orientation table and the cube
// map (~0.6 s at the defaults on 2 cores); everything after is const and thread-safe. The cube
// map build and renderFrame() spread rows over cv::parallel_for_ (cv::setNumThreads applies);
// the output does not depend on the thread count.
//
// Determinism: random draws come from std::mt19937 turned into doubles by a fixed formula (never
// the implementation-defined std:: distributions), the noise lattice from a permutation table
// shuffled by those draws, so one seed and config give the same output with any standard library
// whose <cmath> rounds the same way (bit-identical on one platform, as the tests check).
//
// World frame: z up, x forward; at t = 0 the camera looks along world x with image rows
// horizontal (R_wc(0) maps optical x right, y down, z forward to world -y, -z, x).
class SyntheticRotationSequence {
 public:
  // Throws std::invalid_argument with the validate() sentence for a bad config.
  explicit SyntheticRotationSequence(const SyntheticSequenceConfig& config);

  const SyntheticSequenceConfig& config() const { return config_; }
  const CameraModel& camera() const { return camera_; }
  // The rolling-shutter config matching this sequence, for computeRollingShutterHomographies().
  RollingShutterConfig rollingShutterConfig(int patch_count = 6) const;

  int frameCount() const { return frame_count_; }
  double frameStamp(int frame_index) const { return frame_index / config_.frame_rate_hz; }
  // Camera-clock capture time of (possibly fractional) row `row_px` of a frame.
  double rowTime(int frame_index, double row_px) const;

  // IMU samples in the IMU frame, IMU clock, strictly increasing stamps.
  const std::vector<ImuSample>& imuSamples() const { return imu_samples_; }
  // A buffer holding every IMU sample.
  ImuSampleBuffer imuBuffer() const;

  // True motion at camera-clock time t (inside the IMU span).
  Eigen::Vector3d angularVelocityCamera(double t_s) const;  // rad/s, camera frame, noise-free
  Eigen::Matrix3d orientation(double t_s) const;            // R_wc, camera to world

  // The environment colour seen along a world direction (need not be unit), RGB in [0, 1].
  cv::Vec3f environmentColour(const Eigen::Vector3d& direction_world) const;

  // Renders frame `frame_index` (CV_8UC3, RGB order), every row at its own capture time.
  void renderFrame(int frame_index, cv::Mat& rgb) const;

 private:
  struct Sinusoid {
    double amplitude_rad_s;
    double frequency_hz;
    double phase_rad;
  };
  // A coloured rectangle (gnomonic, in the tangent plane at `centre`) or disc on the sphere.
  struct Shape {
    Eigen::Vector3d centre;  // unit
    Eigen::Vector3d axis_u;  // unit tangents at centre
    Eigen::Vector3d axis_v;
    double half_u;  // tangent-plane half extents (tan of half angles); disc: radius
    double half_v;
    double bound_rad;  // angular radius of a cap containing the shape
    bool disc;
    int checkers;      // 0 = plain; else a checkers x checkers pattern
    cv::Vec3f colour;  // RGB in [0, 1]
    cv::Vec3f second_colour;
  };

  void drawMotion(std::uint32_t seed);
  void buildOrientationTable();
  void buildImuSamples(std::uint32_t seed);
  // Paints the procedural environment (noise background + shapes) into the cube map.
  void buildEnvironment(std::uint32_t seed);

  SyntheticSequenceConfig config_;
  CameraModel camera_;
  int frame_count_ = 0;

  Eigen::Vector3d pan_rad_s_ = Eigen::Vector3d::Zero();
  std::vector<Sinusoid> shake_[3];

  double table_begin_s_ = 0.0;  // time of orientation_table_[0]
  double table_step_s_ = 0.0;
  std::vector<Eigen::Matrix3d> orientation_table_;  // R_wc at table_begin_s_ + k * table_step_s_

  std::vector<ImuSample> imu_samples_;

  // Normalised undistorted ray (x/z, y/z) per sub-sample column and row; used when the camera
  // has no distortion (the ray then factors into a column part and a row part).
  std::vector<double> sub_ray_x_;
  std::vector<double> sub_ray_y_;
  // Per sub-sample ray of the distorted image, row-major, when the camera has distortion.
  std::vector<Eigen::Vector2f> sub_ray_xy_;

  std::vector<Shape> shapes_;
  // 6 faces of CV_8UC3 RGB, (environment_face_px + 2)^2: one border texel each side so that a
  // bilinear lookup never leaves its face.
  std::vector<cv::Mat> cube_faces_;
};

}  // namespace deep_ois
