#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/ground_truth/lens_shift_ground_truth.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

constexpr int kPatches = 6;
constexpr double kFramePeriod = 1.0 / 30.0, kReadout = 0.022;

CameraModel testCamera() {
  Eigen::Matrix3d K;
  K << 257.0, 0.0, 179.5, 0.0, 257.0, 134.5, 0.0, 0.0, 1.0;
  return CameraModel(360, 270, K);
}

// A stabiliser-like lens trajectory: a few pixels, smooth, at time t (seconds).
Eigen::Vector2d trueShift(double t) {
  return Eigen::Vector2d(3.0 * std::sin(2 * M_PI * 1.3 * t) + 1.0 * std::sin(2 * M_PI * 7.0 * t),
                         -2.0 * std::cos(2 * M_PI * 0.9 * t) + 0.8 * std::sin(2 * M_PI * 5.0 * t));
}

struct SyntheticRecording {
  std::vector<double> stamps;
  std::vector<LensShiftPairObservation> pairs;
};

// Tracks that obey K(s_b) R K(s_a)^-1 exactly, plus noise and a share of gross outliers.
SyntheticRecording makeRecording(int frames, double noise_px, double outlier_share,
                                 unsigned seed) {
  const CameraModel camera = testCamera();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(0.0, 359.0), uy(0.0, 269.0), unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px), rate(0.0, 0.15);
  SyntheticRecording recording;
  for (int f = 0; f < frames; ++f) recording.stamps.push_back(f * kFramePeriod);
  for (int f = 0; f + 1 < frames; ++f) {
    LensShiftPairObservation pair;
    pair.frame_a = f;
    pair.frame_b = f + 1;
    const Eigen::Vector3d w(rate(rng), rate(rng), 0.3 * rate(rng));  // rad/s
    std::vector<Eigen::Vector2d> s_a, s_b;
    for (int i = 0; i < kPatches; ++i) {
      // The patch's rotation over one frame period (slightly different per patch).
      pair.rotations.push_back(expSO3(w * kFramePeriod * (1.0 + 0.02 * i)));
      const double t_a = recording.stamps[f] + kReadout * (i + 0.5) / kPatches;
      s_a.push_back(trueShift(t_a));
      s_b.push_back(trueShift(t_a + kFramePeriod));
    }
    const std::vector<Eigen::Matrix3d> H =
        lensShiftHomographies(camera.K(), pair.rotations, s_a, s_b);
    for (int k = 0; k < 300; ++k) {
      const Eigen::Vector2d a(ux(rng), uy(rng));
      const int patch = patchIndexOfRow(a.y(), 270, kPatches);
      Eigen::Vector2d b = (H[patch] * a.homogeneous()).hnormalized();
      if (unit(rng) < outlier_share) b += Eigen::Vector2d(8.0 * unit(rng) + 4.0, -6.0);
      b += Eigen::Vector2d(noise(rng), noise(rng));
      FeatureMatch m;
      m.point_a_px = cv::Point2f(static_cast<float>(a.x()), static_cast<float>(a.y()));
      m.point_b_px = cv::Point2f(static_cast<float>(b.x()), static_cast<float>(b.y()));
      pair.matches.push_back(m);
    }
    recording.pairs.push_back(pair);
  }
  return recording;
}

LensShiftOptions options() {
  LensShiftOptions o;
  o.patch_count = kPatches;
  o.readout_time_s = kReadout;
  return o;
}

// Largest error of the per-patch lens motion s_b - s_a, which is what a pair's image motion holds.
double worstMotionErrorPx(const SyntheticRecording& recording, const LensShiftTrajectory& estimate) {
  double worst = 0.0;
  for (const LensShiftPairObservation& pair : recording.pairs) {
    for (int i = 0; i < kPatches; ++i) {
      const double t_a = recording.stamps[pair.frame_a] + kReadout * (i + 0.5) / kPatches;
      const Eigen::Vector2d truth = trueShift(t_a + kFramePeriod) - trueShift(t_a);
      const Eigen::Vector2d estimated =
          estimate.shift_px[pair.frame_b][i] - estimate.shift_px[pair.frame_a][i];
      worst = std::max(worst, (truth - estimated).norm());
    }
  }
  return worst;
}

TEST(LensShiftGroundTruth, RecoversTheLensMotionFromNoisyTracksWithOutliers) {
  const SyntheticRecording recording = makeRecording(40, 0.2, 0.15, 7);
  const LensShiftTrajectory estimate =
      estimateLensShiftTrajectory(testCamera(), recording.stamps, recording.pairs, options());
  const double worst = worstMotionErrorPx(recording, estimate);
  // Without the lens (the gyro alone) the motion is off by the whole lens motion.
  LensShiftTrajectory gyro_only = estimate;
  for (auto& frame : gyro_only.shift_px)
    for (auto& s : frame) s.setZero();
  const double gyro_worst = worstMotionErrorPx(recording, gyro_only);
  std::printf("lens motion error: worst %.4f px (gyro alone %.3f px)\n", worst, gyro_worst);
  EXPECT_LT(worst, 0.15);
  EXPECT_GT(gyro_worst, 1.0);
  // Outliers are recognised: about 85 % of the 300 tracks of a pair stay.
  for (int inliers : estimate.pair_inliers) EXPECT_NEAR(255, inliers, 30);
}

TEST(LensShiftGroundTruth, ExactTracksGiveTheExactMotion) {
  const SyntheticRecording recording = makeRecording(12, 0.0, 0.0, 3);
  const LensShiftTrajectory estimate =
      estimateLensShiftTrajectory(testCamera(), recording.stamps, recording.pairs, options());
  EXPECT_LT(worstMotionErrorPx(recording, estimate), 0.02);
  for (double r : estimate.pair_median_residual_px) EXPECT_LT(r, 0.01);
}

TEST(LensShiftGroundTruth, HomographiesAreTheShiftedPrincipalPointModel) {
  const Eigen::Matrix3d K = testCamera().K();
  const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(0.01, -0.02, 0.003));
  const Eigen::Vector2d s_a(1.5, -2.0), s_b(-0.5, 3.0);
  const Eigen::Matrix3d H = lensShiftHomographies(K, {R}, {s_a}, {s_b}).front();
  // T(s_b) K R K^-1 T(-s_a) applied to a point.
  const Eigen::Vector2d p(100.0, 200.0);
  const Eigen::Vector2d expected =
      (K * R * K.inverse() * (p - s_a).homogeneous()).hnormalized() + s_b;
  EXPECT_MATRIX_NEAR(expected, (H * p.homogeneous()).hnormalized(), 1e-9);
}

TEST(LensShiftGroundTruth, RefusesInconsistentInput) {
  SyntheticRecording recording = makeRecording(4, 0.0, 0.0, 1);
  recording.pairs[0].rotations.pop_back();
  EXPECT_THROW(estimateLensShiftTrajectory(testCamera(), recording.stamps, recording.pairs,
                                           options()),
               std::invalid_argument);
  recording = makeRecording(4, 0.0, 0.0, 1);
  recording.pairs[1].frame_b = 9;
  EXPECT_THROW(estimateLensShiftTrajectory(testCamera(), recording.stamps, recording.pairs,
                                           options()),
               std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
