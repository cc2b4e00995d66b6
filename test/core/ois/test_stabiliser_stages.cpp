// The stages of the stabiliser model (core/ois/stabiliser_stage.h): each fitted parameter reads and
// writes the field it names within bounds the fit can start from; each stage writes exactly the
// file keys it declares, reads them back, and its validation names its own field; the fit's review
// reports a parameter on a stage's bound by that stage's name.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/ois/stabiliser_stage.h"
#include "deep_ois/core/ois/stages/actuator.h"
#include "deep_ois/core/ois/stages/actuator_coupling.h"
#include "deep_ois/core/ois/stages/centring.h"
#include "deep_ois/core/ois/stages/excursion_centring.h"
#include "deep_ois/core/ois/stages/linear_dynamics.h"
#include "deep_ois/core/ois/stages/pan_detection.h"
#include "deep_ois/core/ois/stages/sampled_controller.h"
#include "deep_ois/core/ois/stages/stroke.h"

namespace deep_ois {
namespace {

// Every mechanism in use, every value inside the fit's bounds.
StabiliserModel everyMechanism() {
  StabiliserModel p;
  p.get<CentringValues>().gain << 0.02, 0.93, -1.01, -0.03;
  p.get<CentringValues>().highpass_corner_hz = 0.7;
  ActuatorValues& actuator = p.get<ActuatorValues>();
  actuator.actuator_natural_hz = 33.0;
  actuator.actuator_damping = 0.62;
  actuator.sensor_lag_s = 0.0015;
  StrokeValues& stroke = p.get<StrokeValues>();
  stroke.stroke_x_deg = 0.8;
  stroke.stroke_y_deg = 0.9;
  stroke.circular_stroke = true;
  stroke.anti_windup = true;
  p.get<ExcursionCentringValues>().excursion_centring = 1.5;
  p.get<ActuatorCouplingValues>().actuator_coupling = Eigen::Vector2d(0.1, -0.08);
  p.get<PanDetectionValues>().pan_detection_rate_rad_s = 0.6;
  p.get<PanDetectionValues>().pan_release_corner_hz = 4.0;
  LinearDynamicsValues& linear = p.get<LinearDynamicsValues>();
  linear.basis.pole_hz = 2.0;
  linear.basis.order = 2;
  linear.coefficients = Eigen::MatrixXd::Constant(2, 6, 0.01);
  // A sampled controller's stages (a generated design's).
  p.set(GyroLoopValues()).roll_deg = 3.0;
  p.set(MotionModeValues()).action = "hold";
  p.set(IntendedMotionValues()).kind = "kalman_cv";
  p.set(TravelValues()).anti_windup = "clamp";
  p.set(HallActuatorValues()).hall_c3 = 0.05;
  return p;
}

TEST(StabiliserStages, AModelIsAnOrderedListOfStagesWithTheirValues) {
  const StabiliserModel chain;
  EXPECT_TRUE(chain.hasDefaultChain());
  EXPECT_FALSE(chain.has("gyro_loop"));
  EXPECT_EQ(stabiliserComposition(chain), (std::vector<std::string>{"centring", "stroke", "actuator"}));
  // Added in the chain's order, whatever the order they are set in; a copy owns its own values.
  StabiliserModel design(std::vector<std::string>{});
  design.set(TravelValues()).shape = "ellipse";
  design.set(GyroLoopValues());
  design.set(IntendedMotionValues());
  EXPECT_EQ(design.stageNames(),
            (std::vector<std::string>{"gyro_loop", "intended_motion", "travel"}));
  EXPECT_FALSE(design.hasDefaultChain());
  StabiliserModel copy = design;
  copy.get<TravelValues>().shape = "box";
  EXPECT_EQ(design.get<TravelValues>().shape, "ellipse");
  EXPECT_EQ(design.find<StrokeValues>(), nullptr);
  EXPECT_THROW(design.get<StrokeValues>(), std::logic_error);
  // only(): the named stages, with their values where the model has them.
  const StabiliserModel kept = everyMechanism().only({"linear_dynamics", "stroke:soft", "actuator"});
  EXPECT_EQ(kept.stageNames(), (std::vector<std::string>{"linear_dynamics", "stroke", "actuator"}));
  EXPECT_EQ(kept.get<StrokeValues>().stroke_x_deg, 0.8);
  EXPECT_THROW(StabiliserModel(std::vector<std::string>{"no_such_stage"}), std::invalid_argument);
}

TEST(StabiliserStages, FittedParametersReadAndWriteTheirOwnField) {
  const StabiliserModel p = everyMechanism();
  std::set<std::string> names;
  for (const StageInstance& instance : p.stages()) {
    for (const FittedStabiliserParameter& parameter : instance.stage->fitted) {
      SCOPED_TRACE(std::string(instance.stage->name) + ": " + parameter.name);
      names.insert(parameter.name);
      EXPECT_LT(parameter.lower, parameter.upper);
      EXPECT_GT(parameter.fit_step, 0.0);
      if (parameter.logarithmic) {
        EXPECT_GT(parameter.lower, 0.0);
      }
      const double value = parameter.value(*instance.values);
      EXPECT_GE(value, parameter.lower);
      EXPECT_LE(value, parameter.upper);
      // Setting it changes this parameter and no other.
      StabiliserModel moved = p;
      const double other = 0.5 * (value + (std::isfinite(parameter.upper) ? parameter.upper : value + 2.0));
      parameter.set(*moved.values(instance.stage->name), other);
      EXPECT_DOUBLE_EQ(fittedValue(parameter, moved), other);
      for (const StageInstance& each : p.stages())
        for (const FittedStabiliserParameter& rest : each.stage->fitted)
          if (&rest != &parameter) {
            EXPECT_EQ(fittedValue(rest, moved), fittedValue(rest, p)) << rest.what;
          }
      if (parameter.used) {
        EXPECT_TRUE(parameter.used(*instance.values));
      }
    }
  }
  // The names the training report and the review use.
  for (const char* name : {"highpass_corner_hz", "actuator_natural_hz", "actuator_damping",
                           "sensor_lag_s", "stroke_x_deg", "stroke_y_deg", "excursion_centring",
                           "actuator_coupling", "pan_release_corner_hz"})
    EXPECT_EQ(names.count(name), 1u) << name;
  EXPECT_THROW(fittedStabiliserParameter("no_such_parameter"), std::invalid_argument);
  EXPECT_DOUBLE_EQ(fittedValue(fittedStabiliserParameter("sensor_lag_s"), p), 1.5);  // milliseconds
}

// The stage's keys as it writes them for p, and what it writes again after reading them.
std::set<std::string> writtenKeys(const StabiliserStage& stage, const StabiliserModel& p) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  stage.write(out, *p.values(stage.name));
  out << YAML::EndMap;
  const YAML::Node written = YAML::Load(out.c_str());
  std::set<std::string> keys;
  for (const auto& entry : written) keys.insert(entry.first.as<std::string>());
  // Read into the stage's default values, they are p's again.
  std::unique_ptr<StageValues> loaded = stage.make();
  EXPECT_TRUE(stage.read(written, *loaded));
  YAML::Emitter again;
  again << YAML::BeginMap;
  stage.write(again, *loaded);
  again << YAML::EndMap;
  EXPECT_EQ(std::string(again.c_str()), std::string(out.c_str()));
  return keys;
}

TEST(StabiliserStages, EachStageWritesTheKeysItDeclaresAndReadsThemBack) {
  // Anti-windup and the soft stroke exclude each other: one model of each.
  StabiliserModel soft = everyMechanism();
  soft.get<StrokeValues>().anti_windup = false;
  soft.get<StrokeValues>().soft_stroke = true;
  std::set<std::string> all_keys;
  for (const StabiliserStage& stage : stabiliserStages()) {
    SCOPED_TRACE(stage.name);
    std::set<std::string> keys;
    for (const StabiliserModel& p : {everyMechanism(), soft}) {
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
    void (*spoil)(StabiliserModel*);
    const char* field;
  };
  const Case cases[] = {
      {"centring", [](StabiliserModel* p) { p->get<CentringValues>().highpass_corner_hz = -1.0; },
       "highpass_corner_hz"},
      {"actuator", [](StabiliserModel* p) { p->get<ActuatorValues>().sensor_lag_s = 0.2; }, "sensor_lag_s"},
      {"stroke", [](StabiliserModel* p) { p->get<StrokeValues>().soft_stroke = true; },
       "soft_stroke, anti_windup"},
      {"excursion_centring",
       [](StabiliserModel* p) { p->get<ExcursionCentringValues>().excursion_centring = -1.0; },
       "excursion_centring"},
      {"actuator_coupling",
       [](StabiliserModel* p) { p->get<ActuatorCouplingValues>().actuator_coupling.x() = 0.7; },
       "actuator_coupling"},
      {"pan_detection", [](StabiliserModel* p) { p->get<PanDetectionValues>().pan_release_corner_hz = 0.0; },
       "pan_release_corner_hz"},
      {"linear_dynamics",
       [](StabiliserModel* p) {
         LinearDynamicsValues& linear = p->get<LinearDynamicsValues>();
         linear.basis.time_constants_s = {0.01, -0.1};
         linear.basis.order = 2;
       },
       "linear_dynamics: time_constants_s"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.stage);
    StabiliserModel p = everyMechanism();
    c.spoil(&p);
    const std::string why = p.validate();
    EXPECT_EQ(why.rfind(c.field, 0), 0u) << why;
    for (const StageInstance& instance : p.stages()) {
      const std::string own = instance.stage->validate(*instance.values, p);
      if (std::string(instance.stage->name) == c.stage) {
        EXPECT_EQ(own, why);
      } else {
        EXPECT_EQ(own, "") << instance.stage->name;
      }
    }
  }
}

// The sampled controller's words that camera modules use (core/sim/stabiliser_design_runner.h's
// moduleModel) are checked and named as the other fields are.
TEST(StabiliserStages, TheSampledControllersModuleWordsAreValidated) {
  const std::vector<std::string> names = {"gyro_loop", "motion_mode", "intended_motion", "travel",
                                          "hall_actuator"};
  EXPECT_EQ(StabiliserModel(names).validate(), "");
  const std::pair<void (*)(StabiliserModel*), const char*> cases[] = {
      {[](StabiliserModel* p) { p->get<GyroLoopValues>().sampling = "mean"; },
       "gyro_loop.sampling"},
      {[](StabiliserModel* p) { p->get<MotionModeValues>().detector = "peak"; },
       "motion_mode.detector"},
      {[](StabiliserModel* p) { p->get<IntendedMotionValues>().manoeuvre_factor = 0.5; },
       "intended_motion: manoeuvre"},
      {[](StabiliserModel* p) { p->get<TravelValues>().quantiser_lsb_deg = 1.5; },
       "travel: quantiser_lsb_deg"},
      {[](StabiliserModel* p) { p->get<HallActuatorValues>().order = "third"; },
       "hall_actuator.order"},
      {[](StabiliserModel* p) {
         p->get<HallActuatorValues>().order = "pi";
         p->get<HallActuatorValues>().pi_kp = 0.0;
       },
       "hall_actuator: pi_kp"},
  };
  for (const auto& [spoil, field] : cases) {
    StabiliserModel p(names);
    spoil(&p);
    EXPECT_EQ(p.validate().rfind(field, 0), 0u) << p.validate();
  }
  // Sampling at the step's middle is a continuous controller's: not at a slower rate.
  StabiliserModel slow(names);
  slow.get<GyroLoopValues>().sampling = "middle";
  slow.get<GyroLoopValues>().rate_hz = 1000.0;
  EXPECT_THROW(stabiliserRunners(slow, {420.0, 1.0 / 4000.0}), std::invalid_argument);
  EXPECT_NO_THROW(stabiliserRunners(slow, {420.0, 1.0 / 1000.0}));
}

TEST(StabiliserStages, TheReviewNamesAParameterOnItsStagesBound) {
  StabiliserModel p = everyMechanism();
  p.get<PanDetectionValues>().pan_release_corner_hz = fittedStabiliserParameter("pan_release_corner_hz").upper;
  p.get<ActuatorCouplingValues>().actuator_coupling.y() = fittedStabiliserParameter("actuator_coupling").lower;
  const StabiliserFitReview review = reviewStabiliserFit(p);
  EXPECT_TRUE(review.onBound("pan_release_corner_hz"));
  EXPECT_TRUE(review.onBound("actuator_coupling"));
  EXPECT_FALSE(review.onBound("excursion_centring"));
  // Pan detection off: its release corner is not the model's, whatever its value.
  p.get<PanDetectionValues>().pan_detection_rate_rad_s = 0.0;
  EXPECT_FALSE(reviewStabiliserFit(p).onBound("pan_release_corner_hz"));
}

// The linear-dynamics stage over first-order low-passes, added to the lens (the form older files'
// residual banks convert to): for a rate held from rest, each state is the leaky integral
// tau (1 - exp(-t / tau)) of the rate, exactly at every step; the roll axis reaches nothing with
// its coefficients at 0.
TEST(StabiliserStages, LinearDynamicsIntoTheLensFollowsTheLeakyIntegralOfAHeldRate) {
  StabiliserModel p(std::vector<std::string>{"linear_dynamics"});
  LinearDynamicsValues& linear = p.get<LinearDynamicsValues>();
  linear.output_to_lens = true;
  linear.basis.time_constants_s = {0.05, 0.4};
  linear.basis.order = 2;
  linear.coefficients = Eigen::MatrixXd::Zero(2, 6);
  linear.coefficients(0, 0) = 0.5;   // lens x: the 50 ms integral of the x rate
  linear.coefficients(1, 3) = -0.2;  // lens y: the 0.4 s integral of the y rate
  ASSERT_EQ(p.validate(), "");
  const double focal_px = 500.0, step_s = 1e-3;
  StabiliserChain chain(stabiliserRunners(p, StabiliserRunContext{focal_px, step_s}));
  chain.reset();
  const Eigen::Vector3d rate(0.3, -0.1, 0.7);
  double largest_px = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    const Eigen::Vector2d lens = chain.step(rate, rate);
    const double t = k * step_s;
    const Eigen::Vector2d expected(focal_px * 0.5 * 0.3 * 0.05 * (1.0 - std::exp(-t / 0.05)),
                                   focal_px * -0.2 * -0.1 * 0.4 * (1.0 - std::exp(-t / 0.4)));
    largest_px = std::max(largest_px, (lens - expected).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(largest_px, 1e-9);
  EXPECT_EQ(stabiliserComposition(p), (std::vector<std::string>{"linear_dynamics:lens_leaky_x2"}));
}

}  // namespace
}  // namespace deep_ois
