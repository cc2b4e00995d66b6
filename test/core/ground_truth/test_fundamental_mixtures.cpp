#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "test_helpers.h"

namespace deep_ois {
namespace {

constexpr int kWidth = 360;
constexpr int kHeight = 270;
constexpr int kPatches = 6;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// A rolling-shutter frame pair: patch i of frame a moved by R_i (a rate ramp down the frame)
// and a common translation.
struct Scene {
  std::vector<Eigen::Matrix3d> rotations;
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  double min_depth_m = 2.0;
  double max_depth_m = 20.0;
  double noise_px = 0.0;
  double outlier_fraction = 0.0;
  int point_count = 300;
  double row_min_px = 0.0;  // points are drawn with rows in [row_min_px, row_max_px]
  double row_max_px = kHeight - 1.0;
};

// Frame period 1/30 s; the rate ramps across the patches, so each patch's rotation differs.
std::vector<Eigen::Matrix3d> rampRotations(const Eigen::Vector3d& rate_rad_s,
                                           const Eigen::Vector3d& ramp_rad_s_per_patch) {
  std::vector<Eigen::Matrix3d> rotations;
  for (int i = 0; i < kPatches; ++i) {
    rotations.push_back(expSO3((rate_rad_s + i * ramp_rad_s_per_patch) / 30.0));
  }
  return rotations;
}

std::vector<FeatureMatch> makeMatches(const Scene& scene, std::uint32_t seed) {
  const Eigen::Matrix3d K = test::phoneLikeK();
  std::mt19937 rng = streamGenerator(seed, 0);
  std::vector<FeatureMatch> matches;
  while (static_cast<int>(matches.size()) < scene.point_count) {
    const Eigen::Vector2d a(uniform(rng, 5.0, kWidth - 6.0),
                            uniform(rng, scene.row_min_px, scene.row_max_px));
    const double depth = uniform(rng, scene.min_depth_m, scene.max_depth_m);
    const Eigen::Vector3d X_a = depth * (K.inverse() * a.homogeneous());
    const int patch = patchIndexOfRow(a.y(), kHeight, kPatches);
    const Eigen::Vector3d X_b = scene.rotations[patch] * X_a + scene.translation_m;
    Eigen::Vector2d b = (K * X_b).hnormalized();
    if (b.x() < 0.0 || b.y() < 0.0 || b.x() > kWidth - 1.0 || b.y() > kHeight - 1.0) continue;
    Eigen::Vector2d a_noisy = a;
    if (scene.noise_px > 0.0) {
      a_noisy += scene.noise_px * Eigen::Vector2d(gaussian(rng), gaussian(rng));
      b += scene.noise_px * Eigen::Vector2d(gaussian(rng), gaussian(rng));
    }
    if (uniform01(rng) < scene.outlier_fraction) {
      b = Eigen::Vector2d(uniform(rng, 0.0, kWidth - 1.0), uniform(rng, 0.0, kHeight - 1.0));
    }
    FeatureMatch m;
    m.point_a_px = cv::Point2f(static_cast<float>(a_noisy.x()), static_cast<float>(a_noisy.y()));
    m.point_b_px = cv::Point2f(static_cast<float>(b.x()), static_cast<float>(b.y()));
    matches.push_back(m);
  }
  return matches;
}

CameraModel camera() { return CameraModel(kWidth, kHeight, test::phoneLikeK()); }

double angleDeg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_true) {
  return logSO3(R_est.transpose() * R_true).norm() * kRadToDeg;
}

double worstAngleDeg(const FundamentalMixturesResult& result, const Scene& scene) {
  double worst = 0.0;
  for (int i = 0; i < kPatches; ++i) {
    worst = std::max(worst, angleDeg(result.rotations[i], scene.rotations[i]));
  }
  return worst;
}

Scene parallaxScene() {
  Scene scene;
  scene.rotations =
      rampRotations(Eigen::Vector3d(0.4, -0.6, 0.2), Eigen::Vector3d(0.03, 0.05, -0.02));
  scene.translation_m = Eigen::Vector3d(0.04, -0.03, 0.02);
  scene.min_depth_m = 2.0;
  scene.max_depth_m = 10.0;
  return scene;
}

TEST(FundamentalMixturesOptions, ValidateNamesTheBadField) {
  FundamentalMixturesOptions options;
  EXPECT_EQ(options.validate(), "");
  options.weight_sigma_fraction = 0.0;
  EXPECT_NE(options.validate().find("weight_sigma_fraction"), std::string::npos);
  options = FundamentalMixturesOptions();
  options.min_populated_patches = 7;
  EXPECT_NE(options.validate().find("min_populated_patches"), std::string::npos);
  EXPECT_THROW(estimateFundamentalMixtures({}, camera(), options), std::invalid_argument);
}

TEST(FundamentalMixtures, NoiseFreeParallaxRecoversEveryPatchRotation) {
  const Scene scene = parallaxScene();
  const auto result = estimateFundamentalMixtures(makeMatches(scene, 1), camera(), {});
  ASSERT_TRUE(result.ok()) << result.reason;
  EXPECT_EQ(result.model, MotionModel::kFundamentalMixtures);
  EXPECT_EQ(result.inlier_count, scene.point_count);
  ASSERT_EQ(result.rotations.size(), static_cast<size_t>(kPatches));
  const double worst = worstAngleDeg(result, scene);
  std::printf("noise-free mixtures: worst patch rotation error %.2e deg\n", worst);
  EXPECT_LT(worst, 0.01);
  for (int i = 0; i < kPatches; ++i) {
    EXPECT_MATRIX_NEAR(rotationHomography(test::phoneLikeK(), result.rotations[i]),
                       result.homographies[i], 1e-12);
  }
}

// F constrains only the flow across epipolar lines; within one 45-row strip the rotation
// component along them is weakly determined (the rotation / translation ambiguity), so 0.3 px of
// noise costs far more than the 0.1 degree a rotation-only fit achieves. Measured over these
// seeds: worst patch 0.52 degree, mean 0.22 degree; asserted with margin.
TEST(FundamentalMixtures, NoiseAndOutliers) {
  Scene scene = parallaxScene();
  scene.noise_px = 0.3;
  scene.outlier_fraction = 0.2;
  double worst_over_seeds = 0.0, sum = 0.0;
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    const auto result = estimateFundamentalMixtures(makeMatches(scene, seed), camera(), {});
    ASSERT_TRUE(result.ok()) << result.reason;
    EXPECT_EQ(result.model, MotionModel::kFundamentalMixtures) << "seed " << seed;
    // About 80 % of 300 are inliers; a few true inliers fall past 1 px at 0.3 px noise.
    EXPECT_GT(result.inlier_count, 200);
    EXPECT_LT(result.inlier_count, 260);
    worst_over_seeds = std::max(worst_over_seeds, worstAngleDeg(result, scene));
    for (int i = 0; i < kPatches; ++i) sum += angleDeg(result.rotations[i], scene.rotations[i]);
  }
  const double mean = sum / (5 * kPatches);
  std::printf("0.3 px noise, 20 %% outliers: patch rotation error mean %.4f, worst %.4f deg\n",
              mean, worst_over_seeds);
  EXPECT_LT(worst_over_seeds, 1.0);
  EXPECT_LT(mean, 0.35);
}

TEST(FundamentalMixtures, PureRotationUsesTheRotationFallback) {
  Scene scene;
  scene.rotations =
      rampRotations(Eigen::Vector3d(0.4, -0.6, 0.2), Eigen::Vector3d(0.03, 0.05, -0.02));
  for (double noise : {0.0, 0.3}) {
    scene.noise_px = noise;
    scene.outlier_fraction = noise > 0.0 ? 0.2 : 0.0;
    const auto result = estimateFundamentalMixtures(makeMatches(scene, 3), camera(), {});
    ASSERT_TRUE(result.ok()) << result.reason;
    EXPECT_EQ(result.model, MotionModel::kRotationOnlyFallback) << toString(result.model);
    const double worst = worstAngleDeg(result, scene);
    std::printf("pure rotation, %.1f px noise: fallback worst patch error %.2e deg\n", noise,
                worst);
    EXPECT_LT(worst, noise > 0.0 ? 0.15 : 1e-6);  // measured 0.078 deg at 0.3 px
    for (const auto& F : result.fundamentals) EXPECT_EQ(F.norm(), 0.0);
  }
}

TEST(FundamentalMixtures, TooFewMatchesIsRejectedWithAReason) {
  Scene scene = parallaxScene();
  scene.point_count = 10;
  const auto result = estimateFundamentalMixtures(makeMatches(scene, 4), camera(), {});
  EXPECT_FALSE(result.ok());
  EXPECT_EQ(result.status, FundamentalMixturesStatus::kTooFewMatches);
  EXPECT_EQ(result.model, MotionModel::kNone);
  EXPECT_NE(result.reason.find("too few matches"), std::string::npos) << result.reason;
  EXPECT_TRUE(result.rotations.empty());
}

TEST(FundamentalMixtures, AllPointsInOnePatchIsRejectedOrAccurate) {
  Scene scene = parallaxScene();
  scene.row_min_px = 95.0;  // patch 2 holds rows [90, 135)
  scene.row_max_px = 130.0;
  const auto result = estimateFundamentalMixtures(makeMatches(scene, 5), camera(), {});
  if (result.ok()) {
    EXPECT_LT(worstAngleDeg(result, scene), 0.01);
  } else {
    EXPECT_EQ(result.status, FundamentalMixturesStatus::kPointsInOnePatch);
    EXPECT_NE(result.reason.find("row patches"), std::string::npos) << result.reason;
  }
  // Documented default: rejected, since five of the six patches would be pure extrapolation.
  EXPECT_FALSE(result.ok());

  // Allowed by the options, the populated patch is measured and the others follow it.
  FundamentalMixturesOptions lenient;
  lenient.min_populated_patches = 1;
  const auto extrapolated = estimateFundamentalMixtures(makeMatches(scene, 5), camera(), lenient);
  ASSERT_TRUE(extrapolated.ok()) << extrapolated.reason;
  EXPECT_LT(angleDeg(extrapolated.rotations[2], scene.rotations[2]), 0.01);
  for (int i = 0; i < kPatches; ++i) {
    EXPECT_LT(angleDeg(extrapolated.rotations[i], extrapolated.rotations[2]), 1e-6);
  }
}

TEST(FundamentalMixtures, SparsePatchesAreTiedToTheirNeighbours) {
  // Patch 0 gets only 3 points: its F is held by the smoothness rows, not left undetermined.
  Scene scene = parallaxScene();
  auto matches = makeMatches(scene, 6);
  int kept_in_patch0 = 0;
  matches.erase(std::remove_if(matches.begin(), matches.end(),
                               [&](const FeatureMatch& m) {
                                 if (patchIndexOfRow(m.point_a_px.y, kHeight, kPatches) != 0) {
                                   return false;
                                 }
                                 return ++kept_in_patch0 > 3;
                               }),
                matches.end());
  const auto result = estimateFundamentalMixtures(matches, camera(), {});
  ASSERT_TRUE(result.ok()) << result.reason;
  EXPECT_EQ(result.inlier_counts[0], 3);
  // The tie also pulls patch 1 a little towards patch 0 (measured 0.013 degree there).
  for (int i = 1; i < kPatches; ++i) {
    EXPECT_LT(angleDeg(result.rotations[i], scene.rotations[i]), i == 1 ? 0.03 : 0.01)
        << "patch " << i;
  }
  // Between its own (few) points and its neighbour's rotation.
  const double patch0 = angleDeg(result.rotations[0], scene.rotations[0]);
  EXPECT_LT(patch0, angleDeg(scene.rotations[1], scene.rotations[0]) + 0.01);
}

// Asserted on exact tracks, where the only error left is the model's: the mixtures are exact,
// one global F is off by the rolling-shutter ramp; with 20 % outliers (measured 0.04 vs 0.21
// degree). With 0.3 px noise the per-patch F's weak direction (see NoiseAndOutliers) costs
// about as much as this ramp (measured 0.26 vs 0.23 degree), so that is printed, not asserted.
TEST(FundamentalMixtures, MixturesBeatAGlobalFundamentalOnRollingShutter) {
  const double noise_px[] = {0.0, 0.0, 0.3};
  const double outliers[] = {0.0, 0.2, 0.2};
  for (int config = 0; config < 3; ++config) {
    Scene scene = parallaxScene();
    scene.noise_px = noise_px[config];
    scene.outlier_fraction = outliers[config];
    double mixture_sum = 0.0, global_sum = 0.0;
    for (std::uint32_t seed = 11; seed <= 15; ++seed) {
      const auto matches = makeMatches(scene, seed);
      const auto mixture = estimateFundamentalMixtures(matches, camera(), {});
      const auto global = estimateGlobalFundamental(matches, camera(), {});
      ASSERT_TRUE(mixture.ok()) << mixture.reason;
      ASSERT_TRUE(global.ok()) << global.reason;
      ASSERT_EQ(global.homographies.size(), static_cast<size_t>(kPatches));
      for (int i = 1; i < kPatches; ++i) {
        EXPECT_MATRIX_NEAR(global.homographies[0], global.homographies[i], 0.0);
      }
      EXPECT_EQ(mixture.model, MotionModel::kFundamentalMixtures);
      EXPECT_EQ(global.model, MotionModel::kGlobalFundamental);
      for (int i = 0; i < kPatches; ++i) {
        mixture_sum += angleDeg(mixture.rotations[i], scene.rotations[i]);
        global_sum += angleDeg(global.rotations[i], scene.rotations[i]);
      }
    }
    const double mixture_mean = mixture_sum / (5 * kPatches);
    const double global_mean = global_sum / (5 * kPatches);
    std::printf(
        "%.1f px noise, %.0f %% outliers: mean patch rotation error mixtures %.4f deg, "
        "global F %.4f deg\n",
        noise_px[config], 100.0 * outliers[config], mixture_mean, global_mean);
    if (config == 0) {
      EXPECT_LT(mixture_mean, 0.001);
      EXPECT_GT(global_mean, 0.1);
    } else if (config == 1) {
      EXPECT_LT(mixture_mean * 2.5, global_mean);
    }
  }
}

// Hand-held motion: a few millimetres between frames, so parallax of at most a few tenths of a
// pixel, and KLT-like noise. F then fixes its rotations poorly (see ModelSelection); the default
// keeps the rotation-only fit, which must be closer to the truth than the paper's F rotations.
TEST(FundamentalMixtures, SmallParallaxKeepsTheRotationOnlyFit) {
  Scene scene;
  scene.rotations =
      rampRotations(Eigen::Vector3d(0.3, -0.4, 0.1), Eigen::Vector3d(0.03, 0.05, -0.02));
  scene.translation_m = Eigen::Vector3d(0.003, -0.002, 0.001);  // 4 mm: 0.12 m/s at 30 fps
  scene.min_depth_m = 2.0;                                      // parallax up to 0.45 px
  scene.max_depth_m = 20.0;
  scene.noise_px = 0.1;
  scene.outlier_fraction = 0.05;
  FundamentalMixturesOptions paper;
  paper.model_selection = ModelSelection::kFundamental;
  double selected_sum = 0.0, paper_sum = 0.0;
  for (std::uint32_t seed = 21; seed <= 25; ++seed) {
    const auto matches = makeMatches(scene, seed);
    const auto selected = estimateFundamentalMixtures(matches, camera(), {});
    const auto literal = estimateFundamentalMixtures(matches, camera(), paper);
    ASSERT_TRUE(selected.ok()) << selected.reason;
    ASSERT_TRUE(literal.ok()) << literal.reason;
    EXPECT_EQ(selected.model, MotionModel::kRotationOnlyFallback) << "seed " << seed;
    EXPECT_EQ(literal.model, MotionModel::kFundamentalMixtures) << "seed " << seed;
    EXPECT_LT(selected.parallax_share, 0.2);
    EXPECT_EQ(selected.parallax_share, literal.parallax_share);
    for (int i = 0; i < kPatches; ++i) {
      selected_sum += angleDeg(selected.rotations[i], scene.rotations[i]);
      paper_sum += angleDeg(literal.rotations[i], scene.rotations[i]);
    }
  }
  const double selected_mean = selected_sum / (5 * kPatches);
  const double paper_mean = paper_sum / (5 * kPatches);
  std::printf(
      "4 mm translation, 0.1 px noise: mean patch rotation error %.4f deg (default), "
      "%.4f deg (F rotations, the paper's choice)\n",
      selected_mean, paper_mean);
  EXPECT_LT(selected_mean * 1.5, paper_mean);
}

// The paper's literal ||f|| = 1 gauge: with the default near-hard weights its linear stage is
// ill posed (see MixtureScaleGauge), but the refinement starts each patch from whichever of it
// and the global F fits that patch better, so the result must still be right.
TEST(FundamentalMixtures, UnitNormGaugeStillRecoversTheRotations) {
  const Scene scene = parallaxScene();
  FundamentalMixturesOptions options;
  options.scale_gauge = MixtureScaleGauge::kUnitNorm;
  const auto result = estimateFundamentalMixtures(makeMatches(scene, 8), camera(), options);
  ASSERT_TRUE(result.ok()) << result.reason;
  EXPECT_EQ(result.model, MotionModel::kFundamentalMixtures);
  EXPECT_LT(worstAngleDeg(result, scene), 0.01);
}

TEST(FundamentalMixtures, SameInputSameOutput) {
  Scene scene = parallaxScene();
  scene.noise_px = 0.3;
  scene.outlier_fraction = 0.2;
  const auto matches = makeMatches(scene, 7);
  const auto first = estimateFundamentalMixtures(matches, camera(), {});
  const auto second = estimateFundamentalMixtures(matches, camera(), {});
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first.inliers, second.inliers);
  for (int i = 0; i < kPatches; ++i) {
    EXPECT_MATRIX_NEAR(first.rotations[i], second.rotations[i], 0.0);
  }
}

}  // namespace
}  // namespace deep_ois
