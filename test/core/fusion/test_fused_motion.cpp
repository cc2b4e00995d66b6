// The fused motion (fused_motion.h) on synthetic tracks made with known homographies: it keeps the
// prior without evidence, recovers a known per-patch correction, ignores a moving object and falls
// back on a textureless pair.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/fusion/fused_motion.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

constexpr int kPatches = 6;

// A 640x480 phone-like camera with a mild barrel distortion (tracks live on raw pixels).
CameraModel testCamera() {
  Eigen::Matrix3d K;
  K << 520.0, 0.0, 319.5, 0.0, 520.0, 239.5, 0.0, 0.0, 1.0;
  return CameraModel(640, 480, K, {-0.08, 0.02, 0.0, 0.0, 0.0});
}

// The compensated gyro's motion: a rotation per patch and a lens shift, as a stabiliser model gives.
std::vector<Eigen::Matrix3d> priorHomographies(const CameraModel& camera) {
  std::vector<Eigen::Matrix3d> rotations;
  std::vector<Eigen::Vector2d> shift_a, shift_b;
  for (int i = 0; i < kPatches; ++i) {
    rotations.push_back(expSO3(Eigen::Vector3d(0.004, -0.006, 0.002) * (1.0 + 0.03 * i)));
    shift_a.emplace_back(1.0 + 0.1 * i, -0.5);
    shift_b.emplace_back(-1.5 + 0.1 * i, 0.8 - 0.05 * i);
  }
  return lensShiftHomographies(camera.K(), rotations, shift_a, shift_b);
}

// What the prior missed: a smooth correction per patch, of about 0.7 px.
std::vector<PatchCorrection> trueCorrections() {
  std::vector<PatchCorrection> corrections(kPatches);
  for (int i = 0; i < kPatches; ++i) {
    corrections[i].rotation_rad = Eigen::Vector3d(0.4e-3, -0.3e-3, 0.5e-3) * (1.0 + 0.08 * i);
    corrections[i].shift_px = Eigen::Vector2d(0.35 - 0.04 * i, -0.25 + 0.03 * i);
  }
  return corrections;
}

std::vector<Eigen::Matrix3d> correctedMotion(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& prior,
                                             const std::vector<PatchCorrection>& corrections) {
  std::vector<Eigen::Matrix3d> motion;
  for (int i = 0; i < kPatches; ++i) motion.push_back(correctedHomography(camera.K(), prior[i], corrections[i]));
  return motion;
}

// Tracks of `count` random raw pixels moved by `motion` (undistorted pixels, patch by raw row), plus
// Gaussian noise; those inside `object` (raw pixels of frame a) move by `object_motion_px` more.
std::vector<FeatureMatch> syntheticTracks(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& motion,
                                          int count, double noise_px, unsigned seed,
                                          const cv::Rect2d& object = cv::Rect2d(),
                                          const Eigen::Vector2d& object_motion_px = Eigen::Vector2d::Zero()) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(20.0, camera.width() - 21.0), uy(5.0, camera.height() - 6.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<FeatureMatch> matches;
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector2d a_raw(ux(rng), uy(rng));
    const int patch = patchIndexOfRow(a_raw.y(), camera.height(), kPatches);
    Eigen::Vector2d b = test::applyHomography(motion[patch], camera.undistort(a_raw));
    if (object.contains(cv::Point2d(a_raw.x(), a_raw.y()))) b += object_motion_px;
    const Eigen::Vector2d b_raw = camera.distort(b) + Eigen::Vector2d(noise(rng), noise(rng));
    FeatureMatch m;
    m.point_a_px = cv::Point2f(static_cast<float>(a_raw.x()), static_cast<float>(a_raw.y()));
    m.point_b_px = cv::Point2f(static_cast<float>(b_raw.x()), static_cast<float>(b_raw.y()));
    matches.push_back(m);
  }
  return matches;
}

// Mean distance between two motions over a grid of the frame, pixels.
double meanDistancePx(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& first,
                      const std::vector<Eigen::Matrix3d>& second) {
  double sum = 0.0;
  int n = 0;
  for (double y = 4.0; y < camera.height(); y += 16.0) {
    for (double x = 4.0; x < camera.width(); x += 16.0, ++n) {
      const int patch = patchIndexOfRow(y, camera.height(), kPatches);
      const Eigen::Vector2d a = camera.undistort(Eigen::Vector2d(x, y));
      sum += (test::applyHomography(first[patch], a) - test::applyHomography(second[patch], a)).norm();
    }
  }
  return sum / n;
}

void expectPriorBitwise(const std::vector<Eigen::Matrix3d>& prior, const FusedMotion& fused) {
  EXPECT_FALSE(fused.refined);
  ASSERT_EQ(fused.homographies.size(), prior.size());
  for (std::size_t i = 0; i < prior.size(); ++i) EXPECT_TRUE(fused.homographies[i] == prior[i]) << "patch " << i;
  EXPECT_EQ(fused.mean_correction_px, 0.0);
  EXPECT_EQ(fused.reason.rfind("prior kept: ", 0), 0u) << fused.reason;
}

TEST(FusedMotion, NoTracksReturnsThePriorUnchanged) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 0.6};
  const FusedMotion fused = fuseMotion(camera, prior, {});
  expectPriorBitwise(prior.homographies, fused);
  EXPECT_EQ(fused.reason, "prior kept: no tracks");
  EXPECT_EQ(fused.tracks, 0);
}

TEST(FusedMotion, RecoversAKnownPerPatchCorrection) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 0.6};
  const std::vector<Eigen::Matrix3d> truth = correctedMotion(camera, prior.homographies, trueCorrections());
  const double prior_error_px = meanDistancePx(camera, prior.homographies, truth);
  ASSERT_GT(prior_error_px, 0.4);  // the prior is off by what the tracks must find
  const FusedMotion fused = fuseMotion(camera, prior, syntheticTracks(camera, truth, 300, 0.15, 7));
  ASSERT_TRUE(fused.refined) << fused.reason;
  EXPECT_EQ(fused.reason.rfind("refined on ", 0), 0u) << fused.reason;
  const double fused_error_px = meanDistancePx(camera, fused.homographies, truth);
  std::printf("known correction: prior %.5f px from the truth, fused %.5f px; %d inliers; track residual "
              "prior %.5f px, fused %.5f px\n",
              prior_error_px, fused_error_px, fused.inliers, fused.prior_residual_px, fused.fused_residual_px);
  EXPECT_LT(fused_error_px, 0.05) << "prior " << prior_error_px << " px; " << fused.reason;
  EXPECT_NEAR(fused.mean_correction_px, prior_error_px, 0.05);
  EXPECT_LT(fused.fused_residual_px, fused.prior_residual_px);
  EXPECT_GT(fused.inliers, 280);
  for (const PatchCorrection& c : fused.corrections) EXPECT_GT(c.inliers, 20);
}

TEST(FusedMotion, IgnoresAMovingObjectCoveringAThirdOfTheFrame) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 0.6};
  const std::vector<Eigen::Matrix3d> truth = correctedMotion(camera, prior.homographies, trueCorrections());
  // 55 % of the width over 55 % of the height: 30 % of the frame, most of the middle patches.
  const cv::Rect2d object(0.0, 0.2 * camera.height(), 0.55 * camera.width(), 0.55 * camera.height());
  ASSERT_NEAR(object.area() / (camera.width() * camera.height()), 0.30, 0.005);
  for (const Eigen::Vector2d& object_motion_px : {Eigen::Vector2d(4.0, -2.5), Eigen::Vector2d(1.2, 0.8)}) {
    const std::vector<FeatureMatch> matches =
        syntheticTracks(camera, truth, 400, 0.15, 11, object, object_motion_px);
    const FusedMotion fused = fuseMotion(camera, prior, matches);
    ASSERT_TRUE(fused.refined) << fused.reason;
    std::printf("object moving by (%.1f, %.1f) px: fused %.5f px from the truth, %d of %d tracks inliers\n",
                object_motion_px.x(), object_motion_px.y(), meanDistancePx(camera, fused.homographies, truth),
                fused.inliers, fused.tracks);
    EXPECT_LT(meanDistancePx(camera, fused.homographies, truth), 0.08)
        << "object moving by " << object_motion_px.transpose() << " px; " << fused.reason;
    EXPECT_LT(fused.inliers, 0.8 * fused.tracks) << "the object's tracks are not inliers";
  }
}

// The object is textured and the background is not: most tracks are on the object, and the prior's
// sigma comes from checks the object inflated too (1 px). The pair's own scale (its tracks' lower
// quartile) keeps the object out.
TEST(FusedMotion, IgnoresAMovingObjectThatHoldsMostTracks) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 1.0};
  const std::vector<Eigen::Matrix3d> truth = correctedMotion(camera, prior.homographies, trueCorrections());
  const cv::Rect2d object(0.0, 0.2 * camera.height(), 0.55 * camera.width(), 0.55 * camera.height());
  // Every object track and one background track in three: 56 % of the tracks on the object.
  std::vector<FeatureMatch> matches;
  int background = 0;
  for (const FeatureMatch& m : syntheticTracks(camera, truth, 1200, 0.15, 21, object, Eigen::Vector2d(3.0, 2.0)))
    if (object.contains(cv::Point2d(m.point_a_px.x, m.point_a_px.y)) || background++ % 3 == 0) matches.push_back(m);
  int on_object = 0;
  for (const FeatureMatch& m : matches) on_object += object.contains(cv::Point2d(m.point_a_px.x, m.point_a_px.y));
  ASSERT_GT(on_object, 0.55 * matches.size());
  const FusedMotion fused = fuseMotion(camera, prior, matches);
  ASSERT_TRUE(fused.refined) << fused.reason;
  std::printf("object holding most tracks: fused %.5f px from the truth, sigma %.4f px, %d of %d tracks inliers\n",
              meanDistancePx(camera, fused.homographies, truth), fused.sigma_px, fused.inliers, fused.tracks);
  EXPECT_LT(fused.sigma_px, 0.8);
  EXPECT_LT(meanDistancePx(camera, fused.homographies, truth), 0.1) << fused.reason;
}

TEST(FusedMotion, TexturelessPairGivesThePrior) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 0.6};
  const std::vector<Eigen::Matrix3d> truth = correctedMotion(camera, prior.homographies, trueCorrections());
  // Low texture: a handful of noisy tracks.
  const FusedMotion fused = fuseMotion(camera, prior, syntheticTracks(camera, truth, 3, 0.5, 3));
  expectPriorBitwise(prior.homographies, fused);
  EXPECT_LT(meanDistancePx(camera, fused.homographies, prior.homographies), 0.01);
  EXPECT_NE(fused.reason.find("3 tracks"), std::string::npos) << fused.reason;
}

TEST(FusedMotion, TracksThatDisagreeWithThePriorAreNotFollowed) {
  const CameraModel camera = testCamera();
  MotionPrior prior{priorHomographies(camera), 0.6};
  // The whole view moves 5 px away from the prior (a large object fills the frame): not this motion.
  std::vector<Eigen::Matrix3d> other = prior.homographies;
  for (Eigen::Matrix3d& H : other) H = (Eigen::Matrix3d() << 1, 0, 5.0, 0, 1, -3.0, 0, 0, 1).finished() * H;
  std::vector<FeatureMatch> matches = syntheticTracks(camera, other, 300, 0.15, 5);
  const std::vector<FeatureMatch> background =
      syntheticTracks(camera, correctedMotion(camera, prior.homographies, trueCorrections()), 30, 0.15, 6);
  matches.insert(matches.end(), background.begin(), background.end());
  const FusedMotion fused = fuseMotion(camera, prior, matches);
  expectPriorBitwise(prior.homographies, fused);
  EXPECT_NE(fused.reason.find("inconsistent"), std::string::npos) << fused.reason;
}

TEST(FusedMotion, BadInputIsAnErrorNamingIt) {
  const CameraModel camera = testCamera();
  EXPECT_THROW(fuseMotion(camera, MotionPrior{{}, 0.5}, {}), std::invalid_argument);
  EXPECT_THROW(fuseMotion(camera, MotionPrior{priorHomographies(camera), 0.0}, {}), std::invalid_argument);
  FusionOptions options;
  options.outlier_px = 0.1;  // below the Cauchy scale
  try {
    fuseMotion(camera, MotionPrior{priorHomographies(camera), 0.5}, {}, options);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("outlier_px"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deep_ois
