// The stages of the stabiliser model (core/ois/stabiliser_stage.h): each fitted parameter reads and
// writes the field it names within bounds the fit can start from; each stage writes exactly the
// file keys it declares, reads them back, and its validation names its own field; the fit's review
// reports a parameter on a stage's bound by that stage's name.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <string>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {
namespace {

// Every mechanism in use, every value inside the fit's bounds.
StabiliserParameters everyMechanism() {
  StabiliserParameters p;
  p.gain << 0.02, 0.93, -1.01, -0.03;
  p.highpass_corner_hz = 0.7;
  p.actuator_natural_hz = 33.0;
  p.actuator_damping = 0.62;
  p.sensor_lag_s = 0.0015;
  p.stroke_x_deg = 0.8;
  p.stroke_y_deg = 0.9;
  p.circular_stroke = true;
  p.anti_windup = true;
  p.excursion_centring = 1.5;
  p.actuator_coupling = Eigen::Vector2d(0.1, -0.08);
  p.pan_detection_rate_rad_s = 0.6;
  p.pan_release_corner_hz = 4.0;
  p.residual_time_constants_s = {0.01, 0.1};
  p.residual = Eigen::MatrixXd::Constant(2, 4, 0.01);
  p.nonlinear_features = "rate_bank_v1";
  p.nonlinear_residual = Eigen::MatrixXd::Constant(2, nonlinearFeatureCount("rate_bank_v1"), 0.02);
  p.linear_dynamics.basis.pole_hz = 2.0;
  p.linear_dynamics.basis.order = 2;
  p.linear_dynamics.coefficients = Eigen::MatrixXd::Constant(2, 6, 0.01);
  // A sampled controller's stages (a generated design's).
  p.gyro_loop.emplace().roll_deg = 3.0;
  p.motion_mode.emplace().action = "hold";
  p.intended_motion.emplace().kind = "kalman_cv";
  p.travel.emplace().anti_windup = "clamp";
  p.hall_actuator.emplace().hall_c3 = 0.05;
  return p;
}

TEST(StabiliserStages, FittedParametersReadAndWriteTheirOwnField) {
  const StabiliserParameters p = everyMechanism();
  std::set<std::string> names;
  for (const StabiliserStage& stage : stabiliserStages()) {
    for (const FittedStabiliserParameter& parameter : stage.fitted) {
      SCOPED_TRACE(std::string(stage.name) + ": " + parameter.name);
      names.insert(parameter.name);
      EXPECT_LT(parameter.lower, parameter.upper);
      EXPECT_GT(parameter.fit_step, 0.0);
      if (parameter.logarithmic) {
        EXPECT_GT(parameter.lower, 0.0);
      }
      const double value = parameter.value(p);
      EXPECT_GE(value, parameter.lower);
      EXPECT_LE(value, parameter.upper);
      // Setting it changes this parameter and no other.
      StabiliserParameters moved = p;
      const double other = 0.5 * (value + (std::isfinite(parameter.upper) ? parameter.upper : value + 2.0));
      parameter.set(&moved, other);
      EXPECT_DOUBLE_EQ(parameter.value(moved), other);
      for (const StabiliserStage& each : stabiliserStages())
        for (const FittedStabiliserParameter& rest : each.fitted)
          if (&rest != &parameter) {
            EXPECT_EQ(rest.value(moved), rest.value(p)) << rest.what;
          }
      if (parameter.used) {
        EXPECT_TRUE(parameter.used(p));
      }
    }
  }
  // The names the training report and the review use.
  for (const char* name : {"highpass_corner_hz", "actuator_natural_hz", "actuator_damping",
                           "sensor_lag_s", "stroke_x_deg", "stroke_y_deg", "excursion_centring",
                           "actuator_coupling", "pan_release_corner_hz"})
    EXPECT_EQ(names.count(name), 1u) << name;
  EXPECT_THROW(fittedStabiliserParameter("no_such_parameter"), std::invalid_argument);
  EXPECT_DOUBLE_EQ(fittedStabiliserParameter("sensor_lag_s").value(p), 1.5);  // milliseconds
}

// The stage's keys as it writes them for p, and what it writes again after reading them.
std::set<std::string> writtenKeys(const StabiliserStage& stage, const StabiliserParameters& p) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  stage.write(out, p);
  out << YAML::EndMap;
  const YAML::Node written = YAML::Load(out.c_str());
  std::set<std::string> keys;
  for (const auto& entry : written) keys.insert(entry.first.as<std::string>());
  // Read into a default model, the stage's part of the model is p's again.
  StabiliserParameters loaded;
  stage.read(written, &loaded);
  YAML::Emitter again;
  again << YAML::BeginMap;
  stage.write(again, loaded);
  again << YAML::EndMap;
  EXPECT_EQ(std::string(again.c_str()), std::string(out.c_str()));
  return keys;
}

TEST(StabiliserStages, EachStageWritesTheKeysItDeclaresAndReadsThemBack) {
  // Anti-windup and the soft stroke exclude each other: one model of each.
  StabiliserParameters soft = everyMechanism();
  soft.anti_windup = false;
  soft.soft_stroke = true;
  std::set<std::string> all_keys;
  for (const StabiliserStage& stage : stabiliserStages()) {
    SCOPED_TRACE(stage.name);
    if (std::string(stage.name) == "learned_lens_dynamics") continue;  // needs a network
    std::set<std::string> keys;
    for (const StabiliserParameters& p : {everyMechanism(), soft}) {
      ASSERT_EQ(p.validate(), "");
      const std::set<std::string> written = writtenKeys(stage, p);
      keys.insert(written.begin(), written.end());
    }
    EXPECT_EQ(keys, std::set<std::string>(stage.file_keys.begin(), stage.file_keys.end()));
    for (const std::string& key : keys) EXPECT_TRUE(all_keys.insert(key).second) << key << " twice";
  }
}

TEST(StabiliserStages, ValidationNamesTheStagesField) {
  struct Case {
    const char* stage;
    void (*spoil)(StabiliserParameters*);
    const char* field;
  };
  const Case cases[] = {
      {"centring", [](StabiliserParameters* p) { p->highpass_corner_hz = -1.0; }, "highpass_corner_hz"},
      {"actuator", [](StabiliserParameters* p) { p->sensor_lag_s = 0.2; }, "sensor_lag_s"},
      {"stroke", [](StabiliserParameters* p) { p->soft_stroke = true; }, "soft_stroke, anti_windup"},
      {"excursion_centring", [](StabiliserParameters* p) { p->excursion_centring = -1.0; },
       "excursion_centring"},
      {"actuator_coupling", [](StabiliserParameters* p) { p->actuator_coupling.x() = 0.7; },
       "actuator_coupling"},
      {"pan_detection", [](StabiliserParameters* p) { p->pan_release_corner_hz = 0.0; },
       "pan_release_corner_hz"},
      {"linear_residual", [](StabiliserParameters* p) { p->residual_time_constants_s[0] = 0.0; },
       "residual_time_constants_s"},
      {"learned_residual", [](StabiliserParameters* p) { p->nonlinear_features = "nope"; },
       "nonlinear_features"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.stage);
    StabiliserParameters p = everyMechanism();
    c.spoil(&p);
    const std::string why = p.validate();
    EXPECT_EQ(why.rfind(c.field, 0), 0u) << why;
    for (const StabiliserStage& stage : stabiliserStages()) {
      const std::string own = stage.validate(p);
      if (std::string(stage.name) == c.stage) {
        EXPECT_EQ(own, why);
      } else {
        EXPECT_EQ(own, "") << stage.name;
      }
    }
  }
}

TEST(StabiliserStages, TheReviewNamesAParameterOnItsStagesBound) {
  StabiliserParameters p = everyMechanism();
  p.pan_release_corner_hz = fittedStabiliserParameter("pan_release_corner_hz").upper;
  p.actuator_coupling.y() = fittedStabiliserParameter("actuator_coupling").lower;
  const StabiliserFitReview review = reviewStabiliserFit(p);
  EXPECT_TRUE(review.onBound("pan_release_corner_hz"));
  EXPECT_TRUE(review.onBound("actuator_coupling"));
  EXPECT_FALSE(review.onBound("excursion_centring"));
  // Pan detection off: its release corner is not the model's, whatever its value.
  p.pan_detection_rate_rad_s = 0.0;
  EXPECT_FALSE(reviewStabiliserFit(p).onBound("pan_release_corner_hz"));
}

TEST(StabiliserStages, ThePhysicalChainClearsTheResidualAndLearnedStages) {
  const StabiliserParameters chain = everyMechanism().physicalChain();
  EXPECT_TRUE(chain.residual_time_constants_s.empty());
  EXPECT_EQ(chain.residual.size(), 0);
  EXPECT_TRUE(chain.nonlinear_features.empty());
  EXPECT_EQ(chain.nonlinear_residual.size(), 0);
  EXPECT_FALSE(chain.learned_dynamics.active());
  EXPECT_TRUE(chain.anti_windup);  // the chain's own mechanisms stay
  EXPECT_EQ(chain.excursion_centring, 1.5);
  for (const StabiliserStage& stage : stabiliserStages())
    EXPECT_EQ(stage.physical, stage.clear == nullptr) << stage.name;
}

}  // namespace
}  // namespace deep_ois
