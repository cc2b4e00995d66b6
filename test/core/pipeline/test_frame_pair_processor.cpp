// The frame-pair processor (core/pipeline/frame_pair_processor.h) on a synthetic hand-held OIS
// camera: its motion against paths that do not go through it (the whole stream run through one
// stabiliser predictor; the logged lens shift, known in closed form), its render against the
// renderer, and its timeline and fallback rules.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
#include "ois/known_stabiliser.h"

namespace deep_ois {
namespace {

constexpr double kFramePeriodS = 1.0 / 30.0;
constexpr double kFirstStampS = 1.5;  // the first pair's frame a (after a second of gyro: the warm-up)
constexpr int kPairs = 24;

// A hand-held camera: a few sines per axis (IMU frame, rad/s).
Eigen::Vector3d angularVelocity(double t_s) {
  return Eigen::Vector3d(0.3 * std::sin(2 * M_PI * 0.7 * t_s) + 0.05 * std::sin(2 * M_PI * 5.1 * t_s),
                         0.4 * std::sin(2 * M_PI * 0.45 * t_s + 1.0) + 0.04 * std::sin(2 * M_PI * 7.3 * t_s),
                         0.1 * std::sin(2 * M_PI * 0.9 * t_s + 2.0));
}

struct SyntheticCamera {
  CameraModel camera;
  RollingShutterConfig timing;
  ImuSampleBuffer imu{10.0};
  SyntheticCamera() {
    Eigen::Matrix3d K;
    K << 500.0, 0.0, 319.5, 0.0, 500.0, 239.5, 0.0, 0.0, 1.0;
    camera = CameraModel(640, 480, K, std::vector<double>{0.05, -0.02, 0.0, 0.0, 0.0});
    timing.patch_count = 6;
    timing.readout_time_s = 0.02;
    timing.time_offset_s = 0.004;
    // The IMU mounted turned by 90 degrees about the optical axis: the rates are rotated.
    timing.imu_to_camera_rotation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (double t = 0.0; t <= 4.0; t += 1.0 / 400.0) imu.add({t, angularVelocity(t)});
  }
  double stampA(int k) const { return kFirstStampS + k * kFramePeriodS; }
  FramePair pair(int k) const {
    FramePair p;
    p.stamp_a_s = stampA(k);
    p.stamp_b_s = stampA(k + 1);
    p.timing = timing;
    p.camera = &camera;
    p.imu = &imu;
    return p;
  }
};

// Largest distance (pixels) between where two homography lists move a lattice of frame a's pixels.
double largestDifferencePx(const std::vector<Eigen::Matrix3d>& a, const std::vector<Eigen::Matrix3d>& b) {
  EXPECT_EQ(a.size(), b.size());
  double largest = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    for (double x = 0.0; x < 640.0; x += 80.0)
      for (double y = 0.0; y < 480.0; y += 80.0) {
        const Eigen::Vector3d p(x, y, 1.0);
        largest = std::max(largest, ((a[i] * p).hnormalized() - (b[i] * p).hnormalized()).norm());
      }
  return largest;
}

double patchTime(const RollingShutterConfig& timing, double stamp_s, int i) { return patchImuTime(timing, stamp_s, i); }

TEST(FramePairProcessor, TheModelPairByPairIsTheWholeStreamThroughOnePredictor) {
  const SyntheticCamera cam;
  // The truth: the model run once over the whole gyro stream, from the warm-up before the first
  // pair (where a fresh processor starts it), and its lens shifts put into K(s_b) R K(s_a)^-1.
  const double start_s = patchTime(cam.timing, cam.stampA(0), 0) - kStabiliserWarmUpS;
  // (It keeps a few hundred ms of history: fed up to each pair's last patch before it is asked.)
  LensShiftPredictor whole(knownStabiliser(), cam.camera.K()(0, 0));
  const std::vector<CameraRateSample> all_rates =
      cameraRates(cam.imu, cam.timing.imu_to_camera_rotation, start_s, 3.9);
  std::size_t fed = 0;

  FramePairProcessor from_imu(knownStabiliser());
  FramePairProcessor from_messages(knownStabiliser());  // as the compensation nodelet: the pair's stream
  const cv::Size grid(160, 120);
  HomographyFlowRenderer renderer(cam.camera, grid, cam.timing.patch_count);
  double largest_px = 0.0, largest_live_px = 0.0, largest_flow_px = 0.0, largest_shift_px = 0.0;
  for (int k = 0; k < kPairs; ++k) {
    const FramePair pair = cam.pair(k);
    const FramePairMotion motion = from_imu.process(pair, grid);
    ASSERT_TRUE(motion.ok) << "pair " << k << ": " << motion.reason;
    EXPECT_EQ(motion.source, PairMotionSource::kStabiliserModel);
    EXPECT_EQ(motion.time_jump_back_s, 0.0);

    // The live path: the gyro's motion given (as a message carries it), the model fed the pair's stream.
    FramePair live = cam.pair(k);
    live.imu = nullptr;
    live.rotations = motion.rotations;
    live.gyro_homographies = motion.gyro_homographies;
    const std::vector<CameraRateSample> stream = pairGyroStream(cam.imu, cam.timing, live.stamp_a_s, live.stamp_b_s);
    live.rates = &stream;
    const FramePairMotion live_motion = from_messages.process(live, grid);
    ASSERT_TRUE(live_motion.ok) << live_motion.reason;

    const double last_patch_s = patchTime(cam.timing, pair.stamp_b_s, cam.timing.patch_count - 1);
    while (fed < all_rates.size() && (fed == 0 || all_rates[fed - 1].stamp_s < last_patch_s))
      whole.addRate(all_rates[fed++]);
    std::vector<Eigen::Vector2d> s_a, s_b;
    for (int i = 0; i < cam.timing.patch_count; ++i) {
      ASSERT_TRUE(whole.covers(patchTime(cam.timing, pair.stamp_a_s, i)));
      s_a.push_back(whole.lensShiftAt(patchTime(cam.timing, pair.stamp_a_s, i)));
      s_b.push_back(whole.lensShiftAt(patchTime(cam.timing, pair.stamp_b_s, i)));
      largest_shift_px = std::max(largest_shift_px, s_b.back().norm());
    }
    const std::vector<Eigen::Matrix3d> truth = lensShiftHomographies(cam.camera.K(), motion.rotations, s_a, s_b);
    largest_px = std::max(largest_px, largestDifferencePx(motion.homographies, truth));
    largest_live_px = std::max(largest_live_px, largestDifferencePx(live_motion.homographies, truth));
    cv::Mat expected_flow;
    renderer.render(truth, expected_flow);
    ASSERT_EQ(motion.flow.size(), grid);
    largest_flow_px = std::max(largest_flow_px, cv::norm(motion.flow, expected_flow, cv::NORM_INF));
  }
  EXPECT_LT(largest_px, 1e-9);
  EXPECT_LT(largest_live_px, 1e-9);
  EXPECT_LT(largest_flow_px, 1e-4);  // float grid
  // Not a trivial agreement: the lens moved by pixels, and differs from the gyro's motion.
  EXPECT_GT(largest_shift_px, 1.0);
  const FramePairMotion last = from_imu.process(cam.pair(kPairs));
  ASSERT_TRUE(last.ok);
  EXPECT_GT(largestDifferencePx(last.homographies, last.gyro_homographies), 0.1);
}

TEST(FramePairProcessor, TheLensLogGivesTheLoggedShiftAndFallsBackToTheGyroWhereItStops) {
  const SyntheticCamera cam;
  // A 200 Hz log of a lens moving linearly in time (exact under the log's linear interpolation),
  // up to 2.0 s of the camera clock.
  auto shift = [](double t_s) { return Eigen::Vector2d(3.0 - 2.0 * t_s, -1.0 + 1.5 * t_s); };
  LensShiftLog log(0.02);
  for (double t = 1.0; t <= 2.0; t += 0.005) ASSERT_TRUE(log.add({t, shift(t), std::nullopt}).accepted());

  FramePairProcessor processor;  // the gyro flow nodelet's: no model
  FramePair covered = cam.pair(3);
  covered.lens_log = &log;
  const FramePairMotion motion = processor.process(covered);
  ASSERT_TRUE(motion.ok) << motion.reason;
  EXPECT_EQ(motion.source, PairMotionSource::kLensLog);
  std::vector<Eigen::Vector2d> s_a, s_b;
  for (int i = 0; i < cam.timing.patch_count; ++i) {
    s_a.push_back(shift(patchCameraTime(cam.timing, covered.stamp_a_s, i)));
    s_b.push_back(shift(patchCameraTime(cam.timing, covered.stamp_b_s, i)));
  }
  EXPECT_LT(largestDifferencePx(motion.homographies,
                                lensShiftHomographies(cam.camera.K(), motion.rotations, s_a, s_b)),
            1e-9);
  // The gyro part is the integration's own.
  const RollingShutterHomographies gyro = FramePairProcessor::gyroMotion(covered);
  ASSERT_TRUE(gyro.ok());
  EXPECT_LT(largestDifferencePx(motion.gyro_homographies, gyro.homographies), 1e-12);

  // A pair past the log's end: the gyro alone, and the reason.
  FramePair past = cam.pair(20);  // frame b at 2.2 s
  past.lens_log = &log;
  const FramePairMotion fallback = processor.process(past);
  ASSERT_TRUE(fallback.ok);
  EXPECT_EQ(fallback.source, PairMotionSource::kGyro);
  EXPECT_NE(fallback.reason.find("stopped before"), std::string::npos) << fallback.reason;
  EXPECT_LT(largestDifferencePx(fallback.homographies, fallback.gyro_homographies), 1e-12);
}

TEST(FramePairProcessor, TimeGoingBackRestartsTheModelUnlessPairsAreInRecordingOrder) {
  const SyntheticCamera cam;
  FramePairProcessor live(knownStabiliser());
  FramePairProcessor evaluator(knownStabiliser(), FramePairProcessor::Timeline::kPairsInOrder);
  for (int k = 0; k < 12; ++k) {
    ASSERT_TRUE(live.process(cam.pair(k)).ok);
    ASSERT_TRUE(evaluator.process(cam.pair(k)).ok);
  }
  // The stream loops back to pair 2: the live processor restarts and answers as a fresh one.
  const FramePairMotion looped = live.process(cam.pair(2));
  ASSERT_TRUE(looped.ok) << looped.reason;
  EXPECT_NEAR(looped.time_jump_back_s, cam.stampA(12) - cam.stampA(2), 1e-9);
  EXPECT_EQ(live.timeJumps(), 1);
  FramePairProcessor fresh(knownStabiliser());
  EXPECT_LT(largestDifferencePx(looped.homographies, fresh.process(cam.pair(2)).homographies), 1e-12);
  // The evaluator's processor keeps its state (no restart): an earlier pair is answered from the
  // model's retained history, or said not to be covered, never from a restarted state.
  const FramePairMotion kept = evaluator.process(cam.pair(2));
  EXPECT_EQ(kept.time_jump_back_s, 0.0);
  EXPECT_EQ(evaluator.timeJumps(), 0);
  EXPECT_EQ(evaluator.stateResets(), 0);
  if (!kept.ok) {
    EXPECT_NE(kept.reason.find("does not cover"), std::string::npos) << kept.reason;
  }
}

TEST(FramePairProcessor, SaysWhyWhenTheGyroDoesNotCoverThePair) {
  const SyntheticCamera cam;
  FramePairProcessor processor(knownStabiliser());
  FramePair late = cam.pair(0);
  late.stamp_a_s = 3.99;  // frame b past the IMU's last sample (4.0 s)
  late.stamp_b_s = 3.99 + kFramePeriodS;
  const FramePairMotion motion = processor.process(late);
  EXPECT_FALSE(motion.ok);
  EXPECT_NE(motion.gyro_status, IntegrationStatus::kOk);
  EXPECT_FALSE(motion.reason.empty());
  FramePair no_camera = cam.pair(0);
  no_camera.camera = nullptr;
  EXPECT_THROW(processor.process(no_camera), std::invalid_argument);
}

// Step 3: tracks that show the model's motion off by a lens shift move the output to them, the
// prior is kept beside it; a fusion that throws keeps the prior and says so.
TEST(FramePairProcessor, TheFusionRefinesTheModelsMotionWithTheTracksAndKeepsItWhenItFails) {
  SyntheticCamera cam;
  cam.camera = CameraModel(640, 480, cam.camera.K());  // no distortion: raw pixels are undistorted
  FramePairProcessor plain(knownStabiliser()), fusing(knownStabiliser()), failing(knownStabiliser());
  const FramePairMotion model = plain.process(cam.pair(0));
  ASSERT_TRUE(model.ok);
  // The truth: the model's motion with 0.8 px more shift across; tracks on a lattice.
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
  shift(0, 2) = 0.8;
  std::vector<Eigen::Matrix3d> truth;
  for (const Eigen::Matrix3d& H : model.homographies) truth.push_back(shift * H);
  std::vector<FeatureMatch> tracks;
  for (double y = 10.0; y < 470.0; y += 20.0)
    for (double x = 20.0; x < 620.0; x += 25.0) {
      const int patch = patchIndexOfRow(y, 480, cam.timing.patch_count);
      const Eigen::Vector2d b = (truth[static_cast<std::size_t>(patch)] * Eigen::Vector3d(x, y, 1.0)).hnormalized();
      tracks.push_back({cv::Point2f(static_cast<float>(x), static_cast<float>(y)),
                        cv::Point2f(static_cast<float>(b.x()), static_cast<float>(b.y()))});
    }
  const FusionOptions options;
  FramePair pair = cam.pair(0);
  pair.fusion = &options;
  pair.tracks = &tracks;
  const FramePairMotion fused = fusing.process(pair, cv::Size(64, 48));
  ASSERT_TRUE(fused.ok);
  ASSERT_TRUE(fused.fused.has_value());
  EXPECT_TRUE(fused.fused->refined) << fused.fused->reason;
  EXPECT_FALSE(fused.fusion_failed);
  EXPECT_EQ(fused.prior_homographies, model.homographies);
  EXPECT_LT(largestDifferencePx(fused.homographies, truth), 0.1);
  EXPECT_GT(largestDifferencePx(model.homographies, truth), 0.7);
  // The render is the fused motion's.
  cv::Mat expected;
  fusing.render(cam.camera, cv::Size(64, 48), fused.homographies, expected);
  EXPECT_EQ(cv::norm(fused.flow, expected, cv::NORM_INF), 0.0);

  pair.prior_sigma_px = -1.0;  // fuseMotion refuses it
  const FramePairMotion failed = failing.process(pair);
  ASSERT_TRUE(failed.ok);
  EXPECT_TRUE(failed.fusion_failed);
  EXPECT_EQ(failed.homographies, model.homographies);
  ASSERT_TRUE(failed.fused.has_value());
  EXPECT_FALSE(failed.fused->refined);
  EXPECT_EQ(failed.fused->reason.rfind("prior kept: the fusion failed", 0), 0u) << failed.fused->reason;
}

}  // namespace
}  // namespace deep_ois
