// Ground truth anchored on the gyro: the OIS lens trajectory of a recording, estimated from point
// tracks with the camera rotation taken from the gyro.
//
// Why: an OIS camera's image motion between a row captured at t_a and the same scene row at t_b is
// K(s(t_b)) R_b_a K(s(t_a))^-1, where K(s) is K with its principal point moved by the lens shift s
// (pixels). With the camera-IMU calibration known, the gyro gives R_b_a; only s is unknown: two
// numbers per row patch and frame, shared by the two frame pairs a frame belongs to. Fitting a
// rotation to the images instead (Fundamental Mixtures) explains a translation of the principal
// point with a rotation, the wrong model for the motion it has to explain.
//
// The estimate: one lens position per (frame, row patch), at the patch's capture time, for the
// whole recording at once. Each track of a pair (a, b) in patch i says
//   p_b = T(s_b,i) H_i T(-s_a,i) p_a,   H_i = K R_b_a,i K^-1,   T(s) = translation by s,
// on undistorted pixels. To first order only s_b - s_a is seen (H is close to the identity), so a
// random-walk prior over time keeps the trajectory smooth where tracks are few, and a weak prior
// holds the lens near the optical centre, where a stabiliser's centring pulls it. Gauss-Newton
// with Huber weights (iteratively reweighted least squares) on a sparse system. Pure Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
// lensShiftHomographies, the motion the trajectory estimated here implies.
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

// One frame pair of a recording: its frames' indices in the recording, the gyro's camera rotation
// per row patch, and the point tracks (raw pixels, OpenCV convention).
struct LensShiftPairObservation {
  int frame_a = 0;  // index of frame a in the recording (frames are 0 .. frame_count - 1)
  int frame_b = 1;  // index of frame b, > frame_a
  // R_b_a per row patch: frame a's camera frame to frame b's, at the patch's rows (the gyro's
  // RollingShutterHomographies::rotations).
  std::vector<Eigen::Matrix3d> rotations;
  std::vector<FeatureMatch> matches;
};

struct LensShiftOptions {
  // Row patches per frame; the rotations of every pair must have this many entries.
  int patch_count = 6;
  // Readout time, seconds: it places the (frame, patch) lens positions in time for the smoothness
  // prior (patch i of frame f at stamp_f + readout * (i + 0.5) / N).
  double readout_time_s = 0.022;
  // Random-walk prior: the lens moves by N(0, rate^2 dt) per axis between consecutive positions
  // dt apart. A voice-coil lens under a position loop moves a few pixels per frame interval.
  double lens_random_walk_px_per_sqrt_s = 15.0;
  // Prior on each position: N(0, sigma^2) per axis (the stabiliser's centring), pixels.
  double centre_prior_px = 20.0;
  // Huber threshold on a track's residual, pixels: beyond it the weight falls as threshold/|r|.
  double huber_px = 0.3;
  // Tracks whose residual exceeds this after the first passes are outliers (weight 0 in the last
  // passes). Tight on purpose: with the rotation known, a background track fits to the KLT noise
  // (~0.1-0.2 px), while a moving object's tracks pull a patch's two unknowns by whole pixels
  // (measured on the simulator's MF recordings: 0.6 px gave 0.22 px geometry distance, 3 px 0.44).
  double outlier_px = 0.6;
  int iterations = 8;  // Gauss-Newton / reweighting passes

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

struct LensShiftTrajectory {
  int patch_count = 0;
  // shift_px[f][i]: the lens shift of frame f at row patch i, pixels (principal point = K's + it).
  std::vector<std::vector<Eigen::Vector2d>> shift_px;
  // Per pair (in input order): tracks used after outlier removal and their median residual, px.
  std::vector<int> pair_inliers;
  std::vector<double> pair_median_residual_px;
};

// Estimates the lens trajectory of a recording from its pairs; `frame_stamps_s` holds every
// frame's stamp (seconds, increasing; the frames the pairs' indices refer to). Frames that no pair
// covers keep the prior (smoothed from their neighbours, else the centre). Throws
// std::invalid_argument when the options are invalid, the stamps do not increase, a pair's frame
// indices are out of range or not increasing, or its rotations do not have patch_count entries.
LensShiftTrajectory estimateLensShiftTrajectory(const CameraModel& camera,
                                                const std::vector<double>& frame_stamps_s,
                                                const std::vector<LensShiftPairObservation>& pairs,
                                                const LensShiftOptions& options);

}  // namespace deep_ois
