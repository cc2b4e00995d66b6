// Pins the model files: every stabiliser model file the repository has (models/, the rostests'
// fixtures) and one of each candidate kind (test/data/stabiliser_models/, written by the code of
// f6a09dd) must load and predict, over a fixed gyro stream, the lens shifts stored beside them in
// <name>.golden.csv to 1e-9 px. The model class is being rebuilt (issue 32); a file a user trained
// must keep predicting what it predicted when it was trained. Files of stages since removed
// (the residual banks) load through the converter to the current form and are held to the
// goldens the removed code wrote; files whose stage has no successor are refused by name.
//
// The golden files are regenerated only on purpose, when a change of prediction is intended:
//   DEEP_OIS_WRITE_STABILISER_GOLDEN=1 devel/lib/deep_ois/test_core --gtest_filter='StabiliserModelFiles.*'
// (it writes the fixtures and the golden files into the source tree; review the diff).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {
namespace {

const std::string kSource = DEEP_OIS_SOURCE_DIR;
const std::string kFixtures = kSource + "/test/data/stabiliser_models/";
constexpr double kTolerancePx = 1e-9;
// Old files whose stage has no successor (relative to the source folder), and the stage each names.
const std::vector<std::pair<std::string, std::string>> kRetiredFixtures = {
    {"test/data/stabiliser_models/retired_learned_lens_dynamics.yaml", "learned_lens_dynamics"},
    {"test/data/stabiliser_models/learned_excursion_v1.yaml", "learned_residual"},
    {"test/data/stabiliser_models/learned_excursion_rate_v1.yaml", "learned_residual"},
};
// A model without a camera (the generic one) is run at this focal length, pixels.
constexpr double kDefaultFocalPx = 500.0;

bool writing() {
  const char* flag = std::getenv("DEEP_OIS_WRITE_STABILISER_GOLDEN");
  return flag && std::string(flag) == "1";
}

// The fixed gyro stream (camera frame, rad/s, 400 Hz, 12 s; sums of sines only, so it is the same
// on every machine): a hand shake, a deliberate pan about y at 0.9 rad/s for 1.2 s (pan detection,
// the stroke and its wind-up), a tilt back and forth past the stroke, then a shake again after a
// 0.3 s gap in the samples (the predictor restarts from a centred lens across it).
std::vector<CameraRateSample> pinnedStream() {
  std::vector<CameraRateSample> rates;
  const double two_pi = 6.283185307179586;
  for (int k = 0; k <= 12 * 400; ++k) {
    const double t = k / 400.0;
    if (t > 8.0 && t < 8.3) continue;  // the gap
    Eigen::Vector3d w;
    w.x() = 0.08 * std::sin(two_pi * 1.3 * t + 0.4) + 0.05 * std::sin(two_pi * 4.7 * t + 1.1) +
            0.03 * std::sin(two_pi * 9.2 * t + 2.0);
    w.y() = 0.07 * std::sin(two_pi * 0.9 * t + 0.2) + 0.06 * std::sin(two_pi * 3.1 * t + 2.4) +
            0.025 * std::sin(two_pi * 11.3 * t + 0.7);
    w.z() = 0.04 * std::sin(two_pi * 0.5 * t);
    if (t >= 3.0 && t < 4.2) w.y() += 0.9 * std::sin(two_pi * (t - 3.0) / 2.4);  // the pan
    if (t >= 5.0 && t < 6.0) w.x() += 0.35 * std::sin(two_pi * (t - 5.0));        // the tilt
    rates.push_back({10.0 + t, w});
  }
  return rates;
}

// The lens shift (pixels) every 20 ms from the stream's start on, each asked as soon as the
// predictor has the samples 5 ms past it (as the nodelet asks); NaN where it does not cover it.
std::vector<Eigen::Vector2d> predictPinned(const StabiliserModel& parameters, double focal_px) {
  LensShiftPredictor predictor(parameters, focal_px);
  const std::vector<CameraRateSample> rates = pinnedStream();
  std::vector<Eigen::Vector2d> shifts;
  std::size_t next = 0;
  for (double query = rates.front().stamp_s; query <= rates.back().stamp_s - 0.005; query += 0.02) {
    while (next < rates.size() && (!predictor.started() || predictor.newestStamp() < query + 0.005))
      predictor.addRate(rates[next++]);
    shifts.push_back(predictor.covers(query)
                         ? predictor.lensShiftAt(query)
                         : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  }
  return shifts;
}

double focalOf(const StabiliserModelFile& file) {
  return file.camera.fx > 0.0 ? file.camera.fx : kDefaultFocalPx;
}

std::string goldenPath(const std::string& name) { return kFixtures + name + ".golden.csv"; }

void writeGolden(const std::string& name, const std::vector<Eigen::Vector2d>& shifts) {
  std::ofstream out(goldenPath(name));
  out << "# lens shift (x, y pixels) every 20 ms over pinnedStream(), "
         "test/core/ois/test_stabiliser_model_files.cpp\n";
  char line[128];
  for (const Eigen::Vector2d& s : shifts) {
    std::snprintf(line, sizeof(line), "%.13g,%.13g\n", s.x(), s.y());
    out << line;
  }
  ASSERT_TRUE(out.good()) << goldenPath(name);
}

std::vector<Eigen::Vector2d> readGolden(const std::string& name) {
  std::ifstream in(goldenPath(name));
  EXPECT_TRUE(in.good()) << "missing " << goldenPath(name);
  std::vector<Eigen::Vector2d> shifts;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t comma = line.find(',');
    shifts.emplace_back(std::strtod(line.substr(0, comma).c_str(), nullptr),
                        std::strtod(line.substr(comma + 1).c_str(), nullptr));
  }
  return shifts;
}

// Largest |predicted - golden| (pixels); infinite when their coverage differs.
double largestDifference(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  if (a.size() != b.size()) return std::numeric_limits<double>::infinity();
  double largest = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (a[k].allFinite() != b[k].allFinite()) return std::numeric_limits<double>::infinity();
    if (a[k].allFinite()) largest = std::max(largest, (a[k] - b[k]).cwiseAbs().maxCoeff());
  }
  return largest;
}

// Loads `path`, compares its prediction with the golden `name`, and checks that the stream
// exercises what the file names: `without` (the mechanism taken out) must predict otherwise. The
// golden of an older file (`converted`: its stages removed since) is never rewritten.
void expectPinned(const std::string& path, const std::string& name,
                  const std::function<void(StabiliserModel*)>& without, bool converted = false) {
  SCOPED_TRACE(path);
  const StabiliserModelFile file = StabiliserModelFile::load(path);
  const std::vector<Eigen::Vector2d> predicted = predictPinned(file.parameters, focalOf(file));
  if (writing() && !converted) writeGolden(name, predicted);
  const std::vector<Eigen::Vector2d> golden = readGolden(name);
  ASSERT_GT(golden.size(), 500u);
  EXPECT_LE(largestDifference(predicted, golden), kTolerancePx)
      << path << " no longer predicts the lens shifts of " << goldenPath(name);
  std::size_t uncovered = 0;
  double largest_px = 0.0;
  for (const Eigen::Vector2d& s : golden) {
    if (!s.allFinite()) ++uncovered;
    else largest_px = std::max(largest_px, s.norm());
  }
  // Only the first step and the 0.3 s gap (15 queries) are not covered; the lens moves by pixels.
  EXPECT_LT(uncovered, 20u);
  if (!without) return;
  EXPECT_GT(largest_px, 0.5);
  StabiliserModel changed = file.parameters;
  without(&changed);
  EXPECT_GT(largestDifference(predictPinned(changed, focalOf(file)), golden), 1e-3)
      << "the pinned stream does not exercise what " << path << " names";
}

// The fixtures: one model of each candidate kind (stabiliser_candidates.h) and of each discrete
// variant of the fit (stroke shape, pan detection), with its mechanism switched off for the
// exercise check.
struct Fixture {
  std::string name;
  std::function<void(StabiliserModel*)> make;     // from the plain chain below; null: an older file
  std::function<void(StabiliserModel*)> without;  // its mechanism out
  bool converted() const { return !make; }
};

StabiliserModel plainChain() {
  StabiliserModel p;
  p.get<CentringValues>().gain << 0.02, 0.93, -1.01, -0.03;
  p.get<CentringValues>().highpass_corner_hz = 0.7;
  p.get<ActuatorValues>().actuator_natural_hz = 33.0;
  p.get<ActuatorValues>().actuator_damping = 0.62;
  p.get<ActuatorValues>().sensor_lag_s = 0.0015;
  p.get<StrokeValues>().stroke_x_deg = 0.8;
  p.get<StrokeValues>().stroke_y_deg = 0.9;
  return p;
}

// The linear filter an older file's residual bank converted to, switched off.
void dropConvertedBank(StabiliserModel* p) { p->get<LinearDynamicsValues>().coefficients.setZero(); }

std::vector<Fixture> fixtures() {
  return {
      {"physical_box_stroke", [](StabiliserModel*) {},
       [](StabiliserModel* p) { p->get<StrokeValues>().stroke_x_deg = p->get<StrokeValues>().stroke_y_deg = 10.0; }},
      {"physical_elliptic_stroke", [](StabiliserModel* p) { p->get<StrokeValues>().circular_stroke = true; },
       [](StabiliserModel* p) { p->get<StrokeValues>().circular_stroke = false; }},
      {"physical_pan_detection",
       [](StabiliserModel* p) {
         p->get<PanDetectionValues>().pan_detection_rate_rad_s = 0.6;
         p->get<PanDetectionValues>().pan_release_corner_hz = 4.0;
       },
       [](StabiliserModel* p) { p->get<PanDetectionValues>().pan_detection_rate_rad_s = 0.0; }},
      // Written with the linear residual bank (removed since): converted on load.
      {"linear_residual", nullptr, dropConvertedBank},
      {"anti_windup", [](StabiliserModel* p) { p->get<StrokeValues>().anti_windup = true; },
       [](StabiliserModel* p) { p->get<StrokeValues>().anti_windup = false; }},
      {"excursion_centring", [](StabiliserModel* p) { p->get<ExcursionCentringValues>().excursion_centring = 1.5; },
       [](StabiliserModel* p) { p->get<ExcursionCentringValues>().excursion_centring = 0.0; }},
      {"anti_windup_excursion_centring",
       [](StabiliserModel* p) {
         p->get<StrokeValues>().anti_windup = true;
         p->get<ExcursionCentringValues>().excursion_centring = 2.0;
       },
       [](StabiliserModel* p) { p->get<ExcursionCentringValues>().excursion_centring = 0.0; }},
      {"actuator_coupling",
       [](StabiliserModel* p) {
         p->get<CentringValues>().gain = Eigen::Matrix2d(Eigen::Rotation2Dd(0.2)) * p->get<CentringValues>().gain;
         p->get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, -0.08);
       },
       [](StabiliserModel* p) { p->get<ActuatorCouplingValues>().actuator_coupling.setZero(); }},
      {"soft_stroke", [](StabiliserModel* p) { p->get<StrokeValues>().soft_stroke = true; },
       [](StabiliserModel* p) { p->get<StrokeValues>().soft_stroke = false; }},
      {"soft_stroke_excursion_centring",
       [](StabiliserModel* p) {
         p->get<StrokeValues>().soft_stroke = true;
         p->get<ExcursionCentringValues>().excursion_centring = 1.2;
       },
       [](StabiliserModel* p) { p->get<ExcursionCentringValues>().excursion_centring = 0.0; }},
      // The mechanisms' interactions: a soft elliptic stroke (the radial tanh), pan detection
      // overriding the excursion-dependent corner while it pans, coupling after the actuator.
      {"soft_elliptic_pan_excursion_coupling",
       [](StabiliserModel* p) {
         p->get<StrokeValues>().circular_stroke = true;
         p->get<StrokeValues>().soft_stroke = true;
         p->get<ExcursionCentringValues>().excursion_centring = 1.4;
         p->get<PanDetectionValues>().pan_detection_rate_rad_s = 0.6;
         p->get<PanDetectionValues>().pan_release_corner_hz = 4.0;
         p->get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(-0.06, 0.09);
       },
       [](StabiliserModel* p) { p->get<PanDetectionValues>().pan_detection_rate_rad_s = 0.0; }},
      {"anti_windup_elliptic_coupling",
       [](StabiliserModel* p) {
         p->get<StrokeValues>().circular_stroke = true;
         p->get<StrokeValues>().anti_windup = true;
         p->get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.07, 0.05);
       },
       [](StabiliserModel* p) { p->get<StrokeValues>().anti_windup = false; }},
      // The linear bank and the learned rate bank (a linear filter too): converted on load.
      {"learned_rate_bank_v1", nullptr, dropConvertedBank},
  };
}

TEST(StabiliserModelFiles, EveryCandidateKindPredictsAsWhenItWasWritten) {
  for (const Fixture& fixture : fixtures()) {
    const std::string path = kFixtures + fixture.name + ".yaml";
    if (writing() && !fixture.converted()) {
      StabiliserModelFile file;
      file.name = "test fixture: " + fixture.name + " (test/core/ois/test_stabiliser_model_files.cpp)";
      file.parameters = plainChain();
      fixture.make(&file.parameters);
      ASSERT_EQ(file.parameters.validate(), "") << fixture.name;
      file.camera = {640, 480, 510.0, 510.0, 319.5, 239.5, 0.03, 30.0};
      file.save(path);
    }
    expectPinned(path, fixture.name, fixture.without, fixture.converted());
  }
}

TEST(StabiliserModelFiles, NoLensMotionPredictsNoShift) {
  const std::string path = kFixtures + "no_lens_motion.yaml";
  if (writing()) {
    StabiliserModelFile file;
    file.name = "test fixture: no lens motion (test/core/ois/test_stabiliser_model_files.cpp)";
    file.parameters = noLensMotion();
    file.camera = {640, 480, 510.0, 510.0, 319.5, 239.5, 0.03, 30.0};
    file.save(path);
  }
  expectPinned(path, "no_lens_motion", {});
  for (const Eigen::Vector2d& s : readGolden("no_lens_motion")) {
    if (s.allFinite()) {
      EXPECT_EQ(s.norm(), 0.0);
    }
  }
}

// The files the repository ships or its rostests load.
TEST(StabiliserModelFiles, TheRepositorysModelsPredictAsWhenTheyWereWritten) {
  auto slower_centring = [](StabiliserModel* p) { p->get<CentringValues>().highpass_corner_hz *= 1.01; };
  expectPinned(kSource + "/models/stabiliser_generic.yaml", "repository_models_stabiliser_generic",
               slower_centring);
  for (const char* name : {"stabiliser_model_learned", "stabiliser_model_structure",
                           "stabiliser_model_other_camera"}) {
    expectPinned(kSource + "/test/ros/" + name + ".yaml", std::string("repository_test_ros_") + name,
                 slower_centring);
  }
}

// A model loaded and saved again is the same file, byte for byte: the writer emits every field
// with the keys, order and precision it had when these files were written (core/ois/
// stabiliser_stage.h: each stage writes its own fields), so a model a tool rewrites does not change
// on disk and a diff of two models shows only what differs.
std::string contentsOf(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A file of this process in the test's temporary folder.
std::string scratchPath(const std::string& name) {
  return ::testing::TempDir() + "/deep_ois_stabiliser_model_" + name + "_" +
         std::to_string(::getpid()) + ".yaml";
}

TEST(StabiliserModelFiles, EveryFixtureSavesToTheSameBytes) {
  std::vector<std::string> paths = {kSource + "/models/stabiliser_generic.yaml",
                                    kSource + "/test/ros/stabiliser_model_learned.yaml",
                                    kFixtures + "no_lens_motion.yaml"};
  for (const Fixture& fixture : fixtures())
    if (!fixture.converted()) paths.push_back(kFixtures + fixture.name + ".yaml");
  const std::string saved = scratchPath("round_trip");
  for (const std::string& path : paths) {
    SCOPED_TRACE(path);
    const std::string original = contentsOf(path);
    ASSERT_FALSE(original.empty());
    StabiliserModelFile::load(path).save(saved);
    EXPECT_EQ(contentsOf(saved), original);
  }
  std::remove(saved.c_str());
}

// An older file (a stage since removed, converted on load) is saved in the current form: the
// linear-dynamics stage its residual banks became. That file predicts the old golden to 1e-9 px,
// and saving it again gives the same bytes.
TEST(StabiliserModelFiles, AnOlderFileIsSavedInTheCurrentFormAndPredictsAsBefore) {
  const std::string once = scratchPath("converted_once");
  const std::string twice = scratchPath("converted_twice");
  for (const Fixture& fixture : fixtures()) {
    if (!fixture.converted()) continue;
    SCOPED_TRACE(fixture.name);
    const std::string path = kFixtures + fixture.name + ".yaml";
    StabiliserModelFile::load(path).save(once);
    const std::string saved = contentsOf(once);
    EXPECT_EQ(saved.find("residual_time_constants_s"), std::string::npos) << saved;
    EXPECT_EQ(saved.find("nonlinear_residual"), std::string::npos) << saved;
    EXPECT_NE(saved.find("output: lens"), std::string::npos) << saved;
    const StabiliserModelFile reread = StabiliserModelFile::load(once);
    EXPECT_LE(largestDifference(predictPinned(reread.parameters, focalOf(reread)), readGolden(fixture.name)),
              kTolerancePx);
    reread.save(twice);
    EXPECT_EQ(contentsOf(twice), saved);
  }
  // A file with both a linear-dynamics stage and a residual bank cannot be one stage: refused.
  std::string both = contentsOf(kFixtures + "linear_residual.yaml");
  both.replace(both.find("camera:"), 7,
               "  linear_dynamics: {pole_hz: 1, order: 1, coefficients: [0, 0, 0, 0, 0, 0]}\ncamera:");
  try {
    StabiliserModelFile::fromYaml(both);
    ADD_FAILURE() << "a file with a linear-dynamics stage and a residual bank loaded";
  } catch (const StabiliserModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find("train_stabiliser"), std::string::npos) << e.what();
  }
  std::remove(once.c_str());
  std::remove(twice.c_str());
}

// Files written by hand or by older code (other comments, fewer digits): saving them once gives
// the writer's form, and saving that again gives the same bytes.
TEST(StabiliserModelFiles, SavingASavedModelAgainGivesTheSameBytes) {
  const std::string once = scratchPath("once");
  const std::string twice = scratchPath("twice");
  for (const char* name : {"stabiliser_model_structure", "stabiliser_model_other_camera"}) {
    const std::string path = kSource + "/test/ros/" + name + ".yaml";
    SCOPED_TRACE(path);
    const StabiliserModelFile original = StabiliserModelFile::load(path);
    original.save(once);
    StabiliserModelFile::load(once).save(twice);
    EXPECT_EQ(contentsOf(twice), contentsOf(once));
    EXPECT_EQ(original.toYaml(), StabiliserModelFile::load(once).toYaml());
  }
  std::remove(once.c_str());
  std::remove(twice.c_str());
}

// Every stabiliser model file the repository holds (models/, test/) is pinned by the tests above: a file added
// without a golden would not be held to its predictions.
TEST(StabiliserModelFiles, EveryCommittedModelFileIsPinned) {
  std::vector<std::string> pinned = {"models/stabiliser_generic.yaml",
                                     "test/data/stabiliser_models/no_lens_motion.yaml"};
  for (const char* name : {"stabiliser_model_learned", "stabiliser_model_structure",
                           "stabiliser_model_other_camera"})
    pinned.push_back(std::string("test/ros/") + name + ".yaml");
  for (const Fixture& fixture : fixtures())
    pinned.push_back("test/data/stabiliser_models/" + fixture.name + ".yaml");
  int found = 0;
  for (const char* folder : {"models", "test"}) {
    for (const auto& entry : std::filesystem::recursive_directory_iterator(kSource + "/" + folder)) {
      if (entry.path().extension() != ".yaml") continue;
      const std::string text = contentsOf(entry.path().string());
      if (text.find("format: deep_ois_stabiliser_model") == std::string::npos) continue;
      const std::string relative = std::filesystem::relative(entry.path(), kSource).string();
      if (std::any_of(kRetiredFixtures.begin(), kRetiredFixtures.end(),
                      [&](const auto& retired) { return retired.first == relative; }))
        continue;  // refused, below
      ++found;
      EXPECT_NE(std::find(pinned.begin(), pinned.end(), relative), pinned.end())
          << relative << " is a stabiliser model file without a golden prediction";
    }
  }
  EXPECT_EQ(found, static_cast<int>(pinned.size()));
}

// An old file with a stage this build no longer has and that no stage can stand in for (the
// pretrained recurrent network; the learned residual of nonlinear features) is refused, naming
// the stage and what to do, never loaded without it.
TEST(StabiliserModelFiles, AFileWithARetiredStageIsRefusedByName) {
  for (const auto& [path, stage] : kRetiredFixtures) {
    SCOPED_TRACE(path);
    try {
      StabiliserModelFile::load(kSource + "/" + path);
      ADD_FAILURE() << "a model with the retired " << stage << " stage loaded";
    } catch (const StabiliserModelFileError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(stage), std::string::npos) << message;
      EXPECT_NE(message.find("retrain"), std::string::npos) << message;
      EXPECT_NE(message.find("train_stabiliser"), std::string::npos) << message;
    }
  }
  // Named in a stages list only, it is refused the same way.
  const std::string text = "format: deep_ois_stabiliser_model\nformat_version: 1\nstabiliser:\n"
                           "  stages: [centring, stroke, actuator, learned_lens_dynamics]\n";
  EXPECT_THROW(
      {
        try {
          StabiliserModelFile::fromYaml(text);
        } catch (const StabiliserModelFileError& e) {
          EXPECT_NE(std::string(e.what()).find("learned_lens_dynamics"), std::string::npos) << e.what();
          throw;
        }
      },
      StabiliserModelFileError);
}

}  // namespace
}  // namespace deep_ois
