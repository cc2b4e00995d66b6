// The stabiliser design generator (core/sim/design_generator.h), its designs' runner and oracle
// and the lens-level traces: deterministic per seed, the oracle is the simulated lens on its own
// gyro, the family covers every class and stage variant, the seeds split, parameters in range.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/sim/camera_motion.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/design_traces.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"
#include "deep_ois/core/sim/stabiliser_oracle.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFocalPx = 257.0;  // RE: 360 px over 70 degrees

DesignTraceOptions shortTrace(double duration_s = 3.0) {
  DesignTraceOptions options;
  options.duration_s = duration_s;
  return options;
}

double largestDifference(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  EXPECT_EQ(a.size(), b.size());
  double largest = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) largest = std::max(largest, (a[i] - b[i]).norm());
  return largest;
}

std::vector<Eigen::Vector2d> panTilt(const std::vector<CameraRateSample>& gyro) {
  std::vector<Eigen::Vector2d> rates;
  for (const CameraRateSample& sample : gyro) rates.push_back(sample.rate_rad_s.head<2>());
  return rates;
}

TEST(DesignGenerator, SameSeedSameLensDifferentSeedsDiffer) {
  for (std::uint32_t seed = 0; seed < 12; ++seed) {
    SCOPED_TRACE("design " + std::to_string(seed));
    EXPECT_EQ(describe(generateDesign(seed)), describe(generateDesign(seed)));
    const DesignTrace first = simulateDesignTrace(seed, 7, shortTrace());
    const DesignTrace again = simulateDesignTrace(seed, 7, shortTrace());
    ASSERT_GT(first.lens_px.size(), 1000u);
    EXPECT_EQ(0.0, largestDifference(first.lens_px, again.lens_px));
    EXPECT_EQ(first.design_class, again.design_class);
    // Another design on the same motion and gyro: another lens.
    const DesignTrace other = simulateDesignTrace(seed + 1000, 7, shortTrace());
    EXPECT_EQ(0.0, largestDifference(panTilt(first.gyro), panTilt(other.gyro)));
    EXPECT_GT(largestDifference(first.lens_px, other.lens_px), 0.1);
  }
}

// The stabiliser's own gyro as runDesign measures it in the simulator (the true rate turned into
// its frame, plus its white noise drawn in the same order), turned back into the camera frame:
// what the oracle is fed to be the simulated stabiliser itself.
std::vector<CameraRateSample> stabiliserGyro(const StabiliserDesign& design, const CameraMotion& motion,
                                             std::uint32_t seed) {
  std::mt19937 rng(seed);
  const double dt = 1.0 / kDesignPhysicsRateHz;
  const int steps = static_cast<int>(std::ceil((motion.endTime() - motion.startTime()) * kDesignPhysicsRateHz));
  const Eigen::Matrix3d to_gyro = design.mount.cameraToGyro();
  std::vector<CameraRateSample> rates = {{motion.startTime(), motion.angularVelocity(motion.startTime())}};
  for (int j = 1; j <= steps; ++j) {
    const double t = motion.startTime() + j * dt;
    if (design.hall.noise_px > 0.0) {  // the Hall reading's draws come first in a step
      gaussian(rng);
      gaussian(rng);
    }
    const double nx = gaussian(rng);
    const double ny = gaussian(rng);
    const Eigen::Vector3d noise(design.mount.noise_rad_s * nx, design.mount.noise_rad_s * ny, 0.0);
    rates.push_back({t, motion.angularVelocity(t) + to_gyro.transpose() * noise});
  }
  return rates;
}

TEST(DesignGenerator, OracleOnItsOwnGyroIsTheSimulatedLens) {
  // Every class and stage variant is among the first 60 seeds (see the coverage test below).
  std::set<std::string> covered;
  for (std::uint32_t seed = 0; seed < 60; ++seed) {
    SCOPED_TRACE(describe(generateDesign(seed)));
    // The Hall reading's noise is not the gyro's: the oracle leaves it out (its mean).
    StabiliserDesign design = generateDesign(seed);
    design.hall.noise_px = 0.0;
    const CameraMotion motion(CameraMotionConfig(), 11 + seed, -0.25, 2.0);
    const int steps = static_cast<int>(std::ceil((motion.endTime() - motion.startTime()) * kDesignPhysicsRateHz));
    std::mt19937 noise(12 + seed);
    const LensShiftGrid truth = runDesign(design, kFocalPx, motion.startTime(), steps,
                                          [&motion](double t) { return motion.angularVelocity(t); }, &noise);
    const StabiliserOracle oracle(design, kFocalPx, stabiliserGyro(design, motion, 12 + seed));
    double largest = 0.0, motion_px = 0.0;
    for (double t = motion.startTime(); t < 1.99; t += 0.00123) {
      largest = std::max(largest, (oracle.lensShift(t) - truth.at(t)).norm());
      motion_px = std::max(motion_px, truth.at(t).norm());
    }
    EXPECT_GT(motion_px, 0.3);  // the lens moves
    EXPECT_LT(largest, 1e-6 * motion_px);
    for (const std::string& tag : designFeatures(design)) covered.insert(tag);
  }
  for (const std::string& tag : designFeatureTags()) {
    EXPECT_TRUE(covered.count(tag)) << tag << " was not checked";
  }
}

TEST(DesignGenerator, SimulatorRunsTheDesignOfOisDesignSeed) {
  // Through the simulator's own path (OisConfig, OisModel), for designs without Hall noise.
  int checked = 0;
  for (std::uint32_t seed = 0; checked < 4 && seed < 200; ++seed) {
    const StabiliserDesign design = generateDesign(seed);
    if (design.hall.noise_px > 0.0) continue;
    SCOPED_TRACE(describe(design));
    OisConfig ois;
    ois.design_seed = seed;
    ois.gain = 0.5;  // not used: the design's keys rule
    const CameraMotion motion(CameraMotionConfig(), 21, -0.25, 2.0);
    const OisModel simulated(ois, motion, kFocalPx, 22);
    const StabiliserOracle from_config(ois, kFocalPx, stabiliserGyro(design, motion, 22));
    const StabiliserOracle from_design(design, kFocalPx, stabiliserGyro(design, motion, 22));
    double largest = 0.0, between = 0.0, motion_px = 0.0;
    for (double t = -0.2; t < 1.99; t += 0.0037) {
      largest = std::max(largest, (from_config.lensShift(t) - simulated.lensShift(t)).norm());
      between = std::max(between, (from_config.lensShift(t) - from_design.lensShift(t)).norm());
      motion_px = std::max(motion_px, simulated.lensShift(t).norm());
    }
    EXPECT_GT(motion_px, 0.3);
    EXPECT_LT(largest, 1e-6 * motion_px);
    EXPECT_EQ(0.0, between);
    ++checked;
  }
  EXPECT_EQ(4, checked);
  // Off is off: the non-OIS twin of a generated design has no lens motion.
  OisConfig off;
  off.design_seed = 3;
  off.enabled = false;
  const CameraMotion motion(CameraMotionConfig(), 21, -0.25, 1.0);
  EXPECT_EQ(0.0, OisModel(off, motion, kFocalPx, 22).lensShift(0.5).norm());
}

// A hand-built design equal to the package's reference camera (phone_main: 0.6 Hz first-order
// centring, 35 Hz second-order actuator with 0.7 damping, 1 deg box stroke) moves the lens as the
// module does: the generated family's stages are the same physics, not another convention.
TEST(DesignGenerator, ADesignBuiltAsTheReferenceModuleMovesItsLens) {
  StabiliserDesign design;
  design.hall.noise_px = 0.0;
  design.actuator.end_stop_margin = 1.0;  // the module's lens stops at its stroke
  ASSERT_EQ("", design.validate());
  const OisConfig module;
  const CameraMotion motion(CameraMotionConfig(), 31, -0.25, 3.0);
  std::vector<CameraRateSample> rates;
  for (double t = -0.25; t < 3.0; t += 0.0025) rates.push_back({t, motion.angularVelocity(t)});
  const StabiliserOracle generated(design, kFocalPx, rates), reference(module, kFocalPx, rates);
  double error = 0.0, lens = 0.0;
  int n = 0;
  for (double t = 0.0; t < 2.9; t += 0.001, ++n) {
    error += (generated.lensShift(t) - reference.lensShift(t)).squaredNorm();
    lens += reference.lensShift(t).squaredNorm();
  }
  std::printf("[ figures  ] reference module as a design: lens %.3f px RMS, difference %.4f px RMS\n",
              std::sqrt(lens / n), std::sqrt(error / n));
  EXPECT_GT(std::sqrt(lens / n), 1.0);
  // The only difference is when the continuous controller samples its gyro (the step's end
  // instead of its mean: 0.125 ms): far below a hundredth of the motion.
  EXPECT_LT(std::sqrt(error / n), 0.01 * std::sqrt(lens / n));
}

TEST(DesignGenerator, EveryClassAndStageVariantAppearsAmongTheFirstSeeds) {
  std::map<std::string, int> count;
  constexpr int kSeeds = 60;
  for (std::uint32_t seed = 0; seed < kSeeds; ++seed) {
    for (const std::string& tag : designFeatures(generateDesign(seed))) ++count[tag];
  }
  for (const std::string& tag : designFeatureTags()) {
    EXPECT_GE(count[tag], 2) << tag << " appears " << count[tag] << " times in the first " << kSeeds << " seeds";
  }
  for (const std::string& name : designClasses()) {
    EXPECT_GE(count[name], kSeeds / 15) << name;
  }
  // And no tag outside the documented list.
  for (const auto& [tag, n] : count) {
    EXPECT_NE(std::find(designFeatureTags().begin(), designFeatureTags().end(), tag), designFeatureTags().end())
        << tag;
  }
}

TEST(DesignGenerator, AtLeastAFifthOfTheSeedsIsHeldOutWithEveryClass) {
  for (const std::uint32_t first : {0u, 12345u, 4294960000u}) {
    int held_out = 0;
    for (std::uint32_t seed = first; seed < first + 1000; ++seed) {
      held_out += designSplit(seed) == DesignSplit::kHeldOut;
    }
    EXPECT_GE(held_out, 200) << "seeds from " << first;
  }
  EXPECT_EQ(DesignSplit::kHeldOut, designSplit(0));
  EXPECT_EQ(DesignSplit::kHeldOut, designSplit(35));
  EXPECT_EQ(DesignSplit::kTraining, designSplit(36));
  EXPECT_STREQ("held_out", toString(DesignSplit::kHeldOut));
  // The first 40 held-out designs (a benchmark's) cover every class.
  std::map<std::string, int> classes;
  for (std::uint32_t seed = 0; seed < 200; seed += 5) ++classes[designClass(generateDesign(seed))];
  for (const std::string& name : designClasses()) EXPECT_GE(classes[name], 3) << name;
}

TEST(DesignGenerator, ParametersAreWithinTheirStatedRanges) {
  for (std::uint32_t seed = 0; seed < 500; ++seed) {
    const StabiliserDesign design = generateDesign(seed);
    ASSERT_EQ("", design.validate()) << seed;
    for (const auto& [name, value] : designParameters(design)) {
      const DesignParameterRange& range = designParameterRange(name);
      EXPECT_GE(value, range.min) << name << " of design " << seed;
      EXPECT_LE(value, range.max) << name << " of design " << seed;
    }
    // DESIGN.md's physics, independently of the table: centring 0.1-2 Hz, actuator tens of Hz to
    // ~100 Hz, stroke +-0.5 to +-1.5 deg.
    EXPECT_GE(design.estimator.corner_hz, 0.1);
    EXPECT_LE(design.estimator.corner_hz, 2.0);
    EXPECT_GE(design.actuator.bandwidth_hz, 20.0);
    EXPECT_LE(design.actuator.bandwidth_hz, 120.0);
    for (double stroke : {design.stroke.x_positive_deg, design.stroke.x_negative_deg,
                          design.stroke.y_positive_deg, design.stroke.y_negative_deg}) {
      EXPECT_GE(stroke, 0.5);
      EXPECT_LE(stroke, 1.5);
    }
  }
  // A value outside its range is named.
  StabiliserDesign design = generateDesign(1);
  design.estimator.corner_hz = 3.0;
  EXPECT_NE(std::string::npos, design.validate().find("estimator.corner_hz")) << design.validate();
  design = generateDesign(1);
  design.loop.rate_hz = 3000.0;
  EXPECT_NE(std::string::npos, design.validate().find("loop.rate_hz")) << design.validate();
  EXPECT_THROW(runDesign(design, kFocalPx, 0.0, 10, [](double) { return Eigen::Vector3d::Zero(); }, nullptr),
               std::invalid_argument);
}

TEST(DesignGenerator, TheLensStabilisesAndStaysWithinItsEndStops) {
  // Every design cancels the shake (its lens moves against the image motion of the rotation) and
  // never passes its end stop: the generated family is a family of stabilisers.
  int stabilising = 0, designs = 0;
  for (std::uint32_t seed = 0; seed < 40; ++seed, ++designs) {
    const StabiliserDesign design = generateDesign(seed);
    const DesignTrace trace = simulateDesignTrace(seed, 100 + seed, shortTrace(4.0));
    const double stop_x = design.actuator.end_stop_margin * kFocalPx *
                          std::tan(std::max(design.stroke.x_positive_deg, design.stroke.x_negative_deg) * kPi / 180.0);
    const double stop_y = design.actuator.end_stop_margin * kFocalPx *
                          std::tan(std::max(design.stroke.y_positive_deg, design.stroke.y_negative_deg) * kPi / 180.0);
    // Lens velocity against the image velocity of the rotation, f (w_y, -w_x), after 1 s.
    double dot = 0.0, lens2 = 0.0, image2 = 0.0;
    for (std::size_t i = 1; i < trace.gyro.size(); ++i) {
      EXPECT_LE(std::abs(trace.lens_px[i].x()), stop_x * (1 + 1e-9)) << seed;
      EXPECT_LE(std::abs(trace.lens_px[i].y()), stop_y * (1 + 1e-9)) << seed;
      if (trace.gyro[i].stamp_s < 1.0) continue;
      const double dt = trace.gyro[i].stamp_s - trace.gyro[i - 1].stamp_s;
      const Eigen::Vector2d lens_velocity = (trace.lens_px[i] - trace.lens_px[i - 1]) / dt;
      const Eigen::Vector3d& w = trace.gyro[i].rate_rad_s;
      const Eigen::Vector2d cancelling(kFocalPx * w.y(), -kFocalPx * w.x());
      dot += lens_velocity.dot(cancelling);
      lens2 += lens_velocity.squaredNorm();
      image2 += cancelling.squaredNorm();
    }
    const double correlation = dot / std::sqrt(lens2 * image2);
    std::printf("[ figures  ] design %2u %-22s lens velocity vs cancelling velocity: correlation %.2f\n",
                seed, trace.design_class.c_str(), correlation);
    stabilising += correlation > 0.5;
  }
  EXPECT_GE(stabilising, designs * 9 / 10);
}

TEST(DesignGenerator, DesignLensShiftsIsTheOracleAtTheGyroStamps) {
  const DesignTrace trace = simulateDesignTrace(4, 5, shortTrace(1.0));
  const StabiliserDesign design = generateDesign(4);
  const std::vector<Eigen::Vector2d> lens = designLensShifts(design, kFocalPx, trace.gyro);
  ASSERT_EQ(lens.size(), trace.gyro.size());
  const StabiliserOracle oracle(design, kFocalPx, trace.gyro);
  for (std::size_t i = 0; i < lens.size(); i += 37) EXPECT_EQ(0.0, (lens[i] - oracle.lensShift(trace.gyro[i].stamp_s)).norm());
  // On the camera's gyro (another noise, bias and rate) it stays close to the true lens: the
  // frame-to-frame (30 Hz) lens motion, what a frame pair's alignment sees, as the oracle test.
  double error = 0.0, motion = 0.0;
  const std::size_t frame = 400 / 30;  // gyro samples per frame at 400 Hz
  for (std::size_t i = 0; i + frame < lens.size(); ++i) {
    const Eigen::Vector2d truth = trace.lens_px[i + frame] - trace.lens_px[i];
    error += (lens[i + frame] - lens[i] - truth).squaredNorm();
    motion += truth.squaredNorm();
  }
  EXPECT_LT(std::sqrt(error), 0.1 * std::sqrt(motion));
  DesignTraceOptions bad;
  bad.imu.time_offset_s = 0.01;
  try {
    simulateDesignTrace(1, 1, bad);
    FAIL() << "a time offset was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string::npos, std::string(e.what()).find("imu.time_offset_s")) << e.what();
  }
}

TEST(DesignGenerator, TheConfigSelectsADesignBySeedAndNamesABadOne) {
  const std::string dir = std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/";
  const std::string overlay = ::testing::TempDir() + "/design_seed.yaml";
  std::ofstream(overlay) << "ois:\n  design_seed: 1234\n";
  EXPECT_EQ(1234, loadSimulatorConfig(dir + "RE.yaml", {overlay}).ois.design_seed);
  EXPECT_EQ(-1, loadSimulatorConfig(dir + "RE.yaml").ois.design_seed);
  for (const char* bad : {"-2", "4294967296", "many"}) {
    std::ofstream(overlay) << "ois:\n  design_seed: " << bad << "\n";
    try {
      loadSimulatorConfig(dir + "RE.yaml", {overlay});
      FAIL() << bad << " was accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string::npos, std::string(e.what()).find("design_seed")) << e.what();
    }
  }
  std::ofstream(overlay) << "ois:\n  design_seed: 3\n  lens_shift_csv: lens.csv\n";
  EXPECT_THROW(loadSimulatorConfig(dir + "RE.yaml", {overlay}), std::runtime_error);
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
