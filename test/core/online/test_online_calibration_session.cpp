// The lens removal the compensation nodelet and benchmark_online_learning --online-calibration
// share (online_calibration_session.h): tracks lose the per-patch lens shift at their own row.
#include <gtest/gtest.h>

#include "deep_ois/core/online/online_calibration_session.h"

namespace deep_ois {
namespace {

Eigen::Matrix3d intrinsics() {
  Eigen::Matrix3d K;
  K << 300.0, 0.0, 180.0, 0.0, 300.0, 135.0, 0.0, 0.0, 1.0;
  return K;
}

OnlineFramePair pairWith(const CameraModel& camera, const std::vector<FeatureMatch>& matches) {
  OnlineFramePair pair;
  pair.stamp_a_s = 1.0;
  pair.stamp_b_s = 1.0 + 1.0 / 30.0;
  pair.camera = camera;
  pair.timing.patch_count = 4;
  pair.timing.patch_time = PatchTimeReference::kPatchStart;
  pair.tracked = true;
  pair.matches = matches;
  return pair;
}

FeatureMatch match(float ua, float va, float ub, float vb) {
  FeatureMatch m;
  m.point_a_px = cv::Point2f(ua, va);
  m.point_b_px = cv::Point2f(ub, vb);
  return m;
}

TEST(OnlineCalibrationLensRemoval, ShiftInterpolatedAtEachTracksRow) {
  const CameraModel camera(360, 270, intrinsics());
  // Patch i's shift is (i, -i) px in frame a and (2i, 0) in frame b; with the patches' first rows
  // as their capture rows, row y sits at patch position 4y/270.
  PairLensShift lens;
  lens.stamp_b_s = 1.0 + 1.0 / 30.0;
  for (int i = 0; i < 4; ++i) {
    lens.shift_a_px.emplace_back(i, -i);
    lens.shift_b_px.emplace_back(2.0 * i, 0.0);
  }
  const OnlineFramePair pair = pairWith(camera, {match(50.f, 101.25f, 60.f, 0.f), match(200.f, 269.f, 210.f, 33.75f)});
  const OnlineFramePair lensless = lenslessPair(pair, &lens);
  ASSERT_EQ(lensless.matches.size(), 2u);
  EXPECT_TRUE(lensless.image_a.empty());
  // Row 101.25: position 1.5 -> a (1.5, -1.5); row 0: b (0, 0).
  EXPECT_NEAR(lensless.matches[0].point_a_px.x, 48.5f, 1e-4);
  EXPECT_NEAR(lensless.matches[0].point_a_px.y, 102.75f, 1e-4);
  EXPECT_NEAR(lensless.matches[0].point_b_px.x, 60.f, 1e-4);
  // Row 269: beyond the last patch's row -> its shift (3, -3); row 33.75: position 0.5 -> b (1, 0).
  EXPECT_NEAR(lensless.matches[1].point_a_px.x, 197.f, 1e-4);
  EXPECT_NEAR(lensless.matches[1].point_a_px.y, 272.f, 1e-4);
  EXPECT_NEAR(lensless.matches[1].point_b_px.x, 209.f, 1e-4);
  EXPECT_NEAR(lensless.matches[1].point_b_px.y, 33.75f, 1e-4);
}

TEST(OnlineCalibrationLensRemoval, ShiftMovesUndistortedPixels) {
  const CameraModel camera(360, 270, intrinsics(), std::vector<double>{-0.2, 0.05});
  PairLensShift lens;
  lens.shift_a_px.assign(4, Eigen::Vector2d(4.0, 2.0));
  lens.shift_b_px.assign(4, Eigen::Vector2d(-3.0, 1.0));
  // Observed: the distorted image of (undistorted point + shift).
  const std::vector<Eigen::Vector2d> truth_a{{30.0, 40.0}, {300.0, 220.0}}, truth_b{{35.0, 41.0}, {296.0, 224.0}};
  std::vector<Eigen::Vector2d> seen_a = truth_a, seen_b = truth_b, want_a = truth_a, want_b = truth_b;
  for (std::size_t k = 0; k < 2; ++k) {
    seen_a[k] += lens.shift_a_px[0];
    seen_b[k] += lens.shift_b_px[0];
  }
  camera.distortPoints(seen_a);
  camera.distortPoints(seen_b);
  camera.distortPoints(want_a);
  camera.distortPoints(want_b);
  std::vector<FeatureMatch> matches;
  for (std::size_t k = 0; k < 2; ++k)
    matches.push_back(match(static_cast<float>(seen_a[k].x()), static_cast<float>(seen_a[k].y()),
                            static_cast<float>(seen_b[k].x()), static_cast<float>(seen_b[k].y())));
  const OnlineFramePair lensless = lenslessPair(pairWith(camera, matches), &lens);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_NEAR(lensless.matches[k].point_a_px.x, want_a[k].x(), 2e-3);
    EXPECT_NEAR(lensless.matches[k].point_a_px.y, want_a[k].y(), 2e-3);
    EXPECT_NEAR(lensless.matches[k].point_b_px.x, want_b[k].x(), 2e-3);
    EXPECT_NEAR(lensless.matches[k].point_b_px.y, want_b[k].y(), 2e-3);
  }
}

TEST(OnlineCalibrationLensRemoval, NoLensOrNoTracks) {
  const CameraModel camera(360, 270, intrinsics());
  OnlineFramePair pair = pairWith(camera, {match(10.f, 20.f, 11.f, 21.f)});
  const OnlineFramePair plain = lenslessPair(pair, nullptr);  // the plain gyro was published
  ASSERT_EQ(plain.matches.size(), 1u);
  EXPECT_EQ(plain.matches[0].point_a_px, pair.matches[0].point_a_px);
  pair.tracked = false;
  PairLensShift lens;
  lens.shift_a_px.assign(4, Eigen::Vector2d(1.0, 1.0));
  lens.shift_b_px = lens.shift_a_px;
  EXPECT_TRUE(lenslessPair(pair, &lens).matches.empty());
}

}  // namespace
}  // namespace deep_ois
