// The simulator's stabilisers pinned: the lens of generated designs of every class
// (runDesign) and of the committed modules (runStabiliser), with and without their sensors' noise,
// on one fixed motion, against lens tracks recorded in test/data/stabiliser_lens_golden/. A
// refactor of the stabiliser chains (one stage library for the simulator and the model) must
// leave them within 1e-9 px. Both are models of the stage library: saved as model files, they
// predict their own lens.
//
// To record them again (only when a change of behaviour is intended, and say why in the commit):
//   DEEP_OIS_WRITE_GOLDEN=1 ./test_sim --gtest_filter='StabiliserLensGolden.*'
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"

namespace deep_ois {
namespace sim {
namespace {

constexpr double kFocalPx = 420.0;
constexpr double kStartS = 12.25;     // not 0: the runners' clocks from a real start
constexpr double kDurationS = 1.6;    // shake, then a pan (pan detection, the stroke, anti-windup)
constexpr int kRecordEvery = 100;     // steps between recorded samples (40 Hz at 4 kHz)
constexpr double kTolerancePx = 1e-9;
constexpr int kDesignsPerClass = 4;

// Shake on all three axes plus a pan about y from 0.5 s to 1.1 s that drives the lens to its stroke.
Eigen::Vector3d angularVelocity(double t_s) {
  const double t = t_s - kStartS;
  const double pan = (t > 0.5 && t < 1.1) ? 0.9 * std::sin(3.14159265358979323846 * (t - 0.5) / 0.6) : 0.0;
  return Eigen::Vector3d(0.12 * std::sin(2.0 * 3.14159265358979323846 * 4.1 * t) +
                             0.05 * std::sin(2.0 * 3.14159265358979323846 * 11.3 * t + 0.4),
                         0.10 * std::sin(2.0 * 3.14159265358979323846 * 2.7 * t + 1.0) +
                             0.04 * std::sin(2.0 * 3.14159265358979323846 * 9.2 * t) + pan,
                         0.08 * std::sin(2.0 * 3.14159265358979323846 * 1.9 * t + 0.3));
}

std::string goldenPath(const std::string& name) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/test/data/stabiliser_lens_golden/" + name + ".csv";
}

// One run's recorded samples: "name,noise,step,x_px,y_px".
struct Track {
  std::vector<std::string> keys;  // "name,noise,step"
  std::vector<Eigen::Vector2d> lens_px;
};

void record(const std::string& name, bool noisy, const LensShiftGrid& grid, int steps,
            double rate_hz, Track* track) {
  for (int j = 0; j <= steps; j += kRecordEvery) {
    track->keys.push_back(name + "," + (noisy ? "1" : "0") + "," + std::to_string(j));
    track->lens_px.push_back(grid.at(kStartS + j / rate_hz));
  }
}

// Writes the track (DEEP_OIS_WRITE_GOLDEN set) or compares it with the recorded one.
void checkAgainstGolden(const std::string& file, const Track& track) {
  const std::string path = goldenPath(file);
  if (std::getenv("DEEP_OIS_WRITE_GOLDEN")) {
    std::ofstream out(path);
    ASSERT_TRUE(out) << "cannot write " << path;
    out << "name,noise,step,x_px,y_px\n";
    char line[128];
    for (std::size_t i = 0; i < track.keys.size(); ++i) {
      std::snprintf(line, sizeof(line), ",%.17g,%.17g\n", track.lens_px[i].x(), track.lens_px[i].y());
      out << track.keys[i] << line;
    }
    return;
  }
  std::ifstream in(path);
  ASSERT_TRUE(in) << "missing golden file " << path;
  std::map<std::string, Eigen::Vector2d> golden;
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string name, noise, step, x, y;
    std::getline(fields, name, ',');
    std::getline(fields, noise, ',');
    std::getline(fields, step, ',');
    std::getline(fields, x, ',');
    std::getline(fields, y, ',');
    golden[name + "," + noise + "," + step] = Eigen::Vector2d(std::stod(x), std::stod(y));
  }
  ASSERT_EQ(golden.size(), track.keys.size()) << path << " records another set of runs";
  double worst = 0.0;
  std::string worst_key;
  for (std::size_t i = 0; i < track.keys.size(); ++i) {
    const auto found = golden.find(track.keys[i]);
    ASSERT_NE(found, golden.end()) << track.keys[i] << " not in " << path;
    const double error = (found->second - track.lens_px[i]).cwiseAbs().maxCoeff();
    if (!(error <= worst)) {
      worst = error;
      worst_key = track.keys[i];
    }
  }
  std::printf("%s: worst deviation %.3g px over %zu samples\n", file.c_str(), worst, track.keys.size());
  EXPECT_LE(worst, kTolerancePx) << "worst at " << worst_key << " (" << path << ")";
}

// The model's predictor on the gyro of the golden motion, sampled at every step of h, against the
// simulator's noise-free lens.
void expectPredictsItsOwnLens(const StabiliserModel& model, const LensShiftGrid& simulated,
                              double h, int steps, const std::string& name) {
  LensShiftPredictor predictor(model, kFocalPx, h);
  double worst = 0.0, largest = 0.0;
  for (int j = 0; j <= steps; ++j) {
    const double t = kStartS + j * h;
    ASSERT_TRUE(predictor.addRate({t, angularVelocity(t)}));
    const Eigen::Vector2d truth = simulated.samples()[static_cast<std::size_t>(j)];
    worst = std::max(worst, (predictor.lensShiftAt(t) - truth).cwiseAbs().maxCoeff());
    largest = std::max(largest, truth.cwiseAbs().maxCoeff());
  }
  std::printf("%s as a model file: worst deviation %.3g px, lens up to %.1f px\n", name.c_str(),
              worst, largest);
  EXPECT_LE(worst, kTolerancePx) << name;
  EXPECT_GT(largest, 1.0) << name << ": the lens hardly moved; the check says little";
}

// A model through its file: saved, loaded, and its composition unchanged.
StabiliserModel throughAFile(const StabiliserModel& model, const std::string& name) {
  StabiliserModelFile file;
  file.name = name;
  file.parameters = model;
  const std::string path = testing::TempDir() + "/stabiliser_" +
                           std::to_string(std::hash<std::string>()(name)) + ".yaml";
  file.save(path);
  const StabiliserModelFile loaded = StabiliserModelFile::load(path);
  std::remove(path.c_str());
  EXPECT_EQ(stabiliserComposition(loaded.parameters), stabiliserComposition(model)) << name;
  return loaded.parameters;
}

const char* const kCommittedModules[] = {"",  // the package's camera (RE.yaml alone)
                                         "phone_main",
                                         "intended_motion_kalman",
                                         "excursion_soft_stroke",
                                         "digital_loop",
                                         "rotated_mount",
                                         "pi_position_loop",
                                         "pan_release",
                                         "hall_noisy_circular",
                                         "over_compensating_asymmetric",
                                         "fast_centring_short_stroke"};

OisConfig committedModule(const std::string& module) {
  const std::string dir = std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/";
  return (module.empty()
              ? loadSimulatorConfig(dir + "RE.yaml")
              : loadSimulatorConfig(dir + "RE.yaml", {dir + "modules/" + module + ".yaml"}))
      .ois;
}

TEST(StabiliserLensGolden, GeneratedDesignsOfEveryClass) {
  // The first kDesignsPerClass seeds of each class: every estimator with a spread of the other
  // stages' choices.
  std::map<std::string, int> taken;
  Track track;
  const int steps = static_cast<int>(std::lround(kDurationS * kDesignPhysicsRateHz));
  for (std::uint32_t seed = 0; taken.size() < designClasses().size() ||
                               std::any_of(taken.begin(), taken.end(),
                                           [](const auto& c) { return c.second < kDesignsPerClass; });
       ++seed) {
    ASSERT_LT(seed, 500u) << "the generator draws too few of some class";
    const StabiliserDesign design = generateDesign(seed);
    int& count = taken[designClass(design)];
    if (count >= kDesignsPerClass) continue;
    ++count;
    const std::string name = std::string(designClass(design)) + "_seed" + std::to_string(seed);
    for (bool noisy : {false, true}) {
      std::mt19937 noise(seed + 1000);
      const LensShiftGrid grid =
          runDesign(design, kFocalPx, kStartS, steps, angularVelocity, noisy ? &noise : nullptr);
      record(name, noisy, grid, steps, kDesignPhysicsRateHz, &track);
    }
  }
  checkAgainstGolden("generated_designs", track);
}

// A generated design is a model of the stage library: saved as a model file, loaded and run by the
// model's predictor on the same gyro, it predicts the simulator's lens (no noise) to 1e-9 px.
TEST(StabiliserLensGolden, AGeneratedDesignSavedAsAModelFilePredictsItsOwnLens) {
  const int steps = static_cast<int>(std::lround(kDurationS * kDesignPhysicsRateHz));
  const double h = 1.0 / kDesignPhysicsRateHz;
  std::map<std::string, int> taken;
  for (std::uint32_t seed = 0; seed < 60; ++seed) {
    const StabiliserDesign design = generateDesign(seed);
    if (taken[designClass(design)]++ >= 2) continue;  // two of each class
    SCOPED_TRACE(describe(design));
    const StabiliserModel loaded =
        throughAFile(designModel(design), "generated design " + std::to_string(seed));
    const std::vector<std::string> composition = stabiliserComposition(loaded);
    EXPECT_NE(std::find(composition.begin(), composition.end(),
                        std::string("intended_motion:") + designClass(design)),
              composition.end());

    const LensShiftGrid simulated = runDesign(design, kFocalPx, kStartS, steps, angularVelocity, nullptr);
    expectPredictsItsOwnLens(loaded, simulated, h, steps,
                             "design " + std::to_string(seed) + " (" + designClass(design) + ")");
  }
  EXPECT_EQ(taken.size(), designClasses().size());
}

// A design file written before the gyro loop's `sampling` (it said `averaged: true|false`) loads as
// the same sampling and predicts the simulator's lens as the file written now does.
TEST(StabiliserLensGolden, ADesignFileWithTheOldAveragedKeyLoadsAsItsSampling) {
  const int steps = static_cast<int>(std::lround(kDurationS * kDesignPhysicsRateHz));
  const double h = 1.0 / kDesignPhysicsRateHz;
  std::map<std::string, int> seen;
  for (std::uint32_t seed = 0; seed < 60 && seen.size() < 2; ++seed) {
    const StabiliserDesign design = generateDesign(seed);
    const StabiliserModel model = designModel(design);
    const std::string sampling = model.get<GyroLoopValues>().sampling;
    if (sampling == "middle" || seen[sampling]++ > 0) continue;  // one averaged, one latest
    StabiliserModelFile file;
    file.name = "design " + std::to_string(seed);
    file.parameters = model;
    std::string text = file.toYaml();
    const std::string now = "sampling: " + sampling;
    ASSERT_NE(text.find(now), std::string::npos) << text;
    text.replace(text.find(now), now.size(), sampling == "averaged" ? "averaged: true" : "averaged: false");
    const StabiliserModel loaded = StabiliserModelFile::fromYaml(text).parameters;
    EXPECT_EQ(loaded.get<GyroLoopValues>().sampling, sampling);
    const LensShiftGrid simulated = runDesign(design, kFocalPx, kStartS, steps, angularVelocity, nullptr);
    expectPredictsItsOwnLens(loaded, simulated, h, steps, "design " + std::to_string(seed) + " (old key)");
  }
  EXPECT_EQ(seen.size(), 2u);
}

TEST(StabiliserLensGolden, CommittedModules) {
  Track track;
  for (const std::string module : kCommittedModules) {
    const OisConfig ois = committedModule(module);
    const int steps = static_cast<int>(std::lround(kDurationS * ois.control_rate_hz));
    for (bool noisy : {false, true}) {
      std::mt19937 noise(77);
      const LensShiftGrid grid =
          runStabiliser(ois, kFocalPx, kStartS, steps, angularVelocity, noisy ? &noise : nullptr);
      record(module.empty() ? "RE" : module, noisy, grid, steps, ois.control_rate_hz, &track);
    }
  }
  checkAgainstGolden("committed_modules", track);
}

// A committed module is a model of the stage library too: saved as a model file, loaded and run by
// the model's predictor, it predicts the simulator's lens (no noise) to 1e-9 px.
TEST(StabiliserLensGolden, ACommittedModuleSavedAsAModelFilePredictsItsOwnLens) {
  for (const std::string module : kCommittedModules) {
    const OisConfig ois = committedModule(module);
    const int steps = static_cast<int>(std::lround(kDurationS * ois.control_rate_hz));
    const StabiliserModel loaded = throughAFile(moduleModel(ois), "module " + module);
    const LensShiftGrid simulated =
        runStabiliser(ois, kFocalPx, kStartS, steps, angularVelocity, nullptr);
    expectPredictsItsOwnLens(loaded, simulated, 1.0 / ois.control_rate_hz, steps,
                             "module " + (module.empty() ? std::string("RE") : module));
  }
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
