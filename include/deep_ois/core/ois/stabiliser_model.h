// A learned model of an optical image stabiliser: predicts where the OIS lens is (a shift of the
// principal point, pixels) from the camera's gyro stream, carrying the stabiliser's state across
// frames.
//
// Why a stateful physical model: an OIS lens position is a causal function of the gyro history.
// The stabiliser integrates its gyro, re-centres (a high-pass with its own corner), lets go during
// deliberate pans, saturates at its stroke and moves the lens through an actuator with its own
// bandwidth and a sensor lag. One inter-frame flow cannot carry that state; a model with the same
// structure and a dozen parameters learned per camera can, and it is cheap (microseconds per
// frame). Linear dynamics no mechanism names are a linear-dynamics stage of free order
// (core/ois/stages/linear_dynamics.h).
//
// Units are normalised by the focal length where it matters (gain as a fraction of the rotation
// cancelled, stroke in degrees), so a model transfers between cameras of one module that differ
// in resolution. Pure C++/Eigen: no ROS.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_signal.h"

namespace deep_ois {

struct StabiliserStage;  // core/ois/stabiliser_stage.h

// One stage's values, owned by the model. Each stage declares its own type (a small header under
// core/ois/stages/ when other code reads it; its file in src/core/ois/stages/ otherwise), derived
// through StageValuesOf, with its stage's name as kStage.
//
// Why type-erased values and not one struct of every mechanism's fields: a mechanism is then one
// file (its values, runner, fitted parameters, file keys) and one registry line, and a model holds
// only the stages it has. The model answers a stage's values by type (find<StrokeValues>()), so
// code that knows a mechanism reads it typed, and code that does not (the file, the fit's
// packing, validation) loops over the stages.
struct StageValues {
  virtual ~StageValues() = default;
  virtual std::unique_ptr<StageValues> clone() const = 0;
};
template <typename Derived>
struct StageValuesOf : StageValues {
  std::unique_ptr<StageValues> clone() const override {
    return std::make_unique<Derived>(static_cast<const Derived&>(*this));
  }
};

// A stage of a model: its description in the registry and its values.
struct StageInstance {
  const StabiliserStage* stage = nullptr;
  std::unique_ptr<StageValues> values;
};

// A stabiliser model: an ordered list of stages (the chain's order, stabiliserStages()), each with
// its values. A stage acts when its values make it act (a pan threshold of 0, no linear-dynamics coefficients:
// the stage is there and does nothing), as every model file before the stage list was written.
class StabiliserModel {
 public:
  // The default chain: every stage of the registry marked in_default_chain (centring, stroke,
  // actuator and the optional mechanisms around them, switched off), with default values.
  StabiliserModel();
  // These stages (names; a token's variant is ignored), with default values, in the chain's
  // order. Throws std::invalid_argument for an unknown name.
  explicit StabiliserModel(const std::vector<std::string>& stage_names);
  StabiliserModel(const StabiliserModel& other);
  StabiliserModel& operator=(const StabiliserModel& other);
  StabiliserModel(StabiliserModel&&) noexcept = default;
  StabiliserModel& operator=(StabiliserModel&&) noexcept = default;

  const std::vector<StageInstance>& stages() const { return stages_; }
  std::vector<std::string> stageNames() const;
  bool has(const std::string& stage) const { return values(stage) != nullptr; }
  // Whether the model has every stage of the default chain (its file then names no stage list).
  bool hasDefaultChain() const;

  // The values of a stage (null when the model has not got it).
  const StageValues* values(const std::string& stage) const;
  StageValues* values(const std::string& stage);
  template <typename V>
  const V* find() const { return static_cast<const V*>(values(V::kStage)); }
  template <typename V>
  V* find() { return static_cast<V*>(values(V::kStage)); }
  // As find, but the stage must be there (std::logic_error naming it otherwise).
  template <typename V>
  const V& get() const { return *static_cast<const V*>(&required(V::kStage)); }
  template <typename V>
  V& get() { return *static_cast<V*>(&required(V::kStage)); }
  // Adds the stage with these values in the chain's order, or replaces its values.
  template <typename V>
  V& set(V v) { return *static_cast<V*>(&put(V::kStage, std::make_unique<V>(std::move(v)))); }
  StageValues& put(const std::string& stage, std::unique_ptr<StageValues> values);
  void remove(const std::string& stage);
  // Only the named stages: those the model has keep their values, the others start at default.
  StabiliserModel only(const std::vector<std::string>& stage_names) const;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;

 private:
  StageValues& required(const char* stage);
  const StageValues& required(const char* stage) const;
  std::vector<StageInstance> stages_;
};

// A camera-frame angular rate sample (IMU clock, seconds; rad/s in the camera optical frame).
struct CameraRateSample {
  double stamp_s = 0.0;
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
};

// Runs the model over a gyro stream and answers the lens shift at any recent time.
class LensShiftPredictor {
 public:
  // Throws std::invalid_argument with the validate() sentence, or for a non-positive focal length
  // or step. `step_s`: the internal integration step (the rate is interpolated linearly between
  // samples); `history_s`: how far back lensShiftAt() can answer.
  LensShiftPredictor(const StabiliserModel& model, double focal_px, double step_s = 1e-3,
                     double history_s = 0.5);

  // Appends a rate sample; samples must come in increasing time. A sample not after the last one
  // is ignored (returns false), unless it is more than max_gap_s before it (time jumped back: the
  // state resets and starts from it). A gap longer than max_gap_s since the previous sample
  // resets the state too (the stabiliser's history is unknown across it): counted in resets().
  bool addRate(const CameraRateSample& sample);
  // Starts over from a centred lens at rest (the state of a stabiliser switched on).
  void reset();

  // The lens shift (pixels, x right, y down) at time t: interpolated between internal steps within
  // the retained history, held after the last step up to the newest sample (less than a step).
  // covers(t) says whether t is inside that span.
  bool covers(double t_s) const;
  Eigen::Vector2d lensShiftAt(double t_s) const;
  double newestStamp() const { return last_stamp_s_; }
  bool started() const { return started_; }
  int resets() const { return resets_; }

  double max_gap_s = 0.1;

 private:
  // One internal step: the rate at its middle (the chain) and at its end (a stage that reads the
  // rate at its own step times): the stages' runners in the chain's order.
  void step(const Eigen::Vector3d& rate_rad_s, const Eigen::Vector3d& end_rate_rad_s);

  double step_s_;
  std::size_t history_steps_;
  // The runners of the stages that act for the model (core/ois/stabiliser_stage.h).
  StabiliserChain chain_;

  // State.
  bool started_ = false;
  double last_stamp_s_ = 0.0;
  Eigen::Vector3d last_rate_ = Eigen::Vector3d::Zero();
  double start_s_ = 0.0;      // stamp of the first sample since the last reset
  long long steps_ = 0;       // internal steps since then
  double clock_s_ = 0.0;      // time of the newest internal step: start_s_ + steps_ * step_s_
  std::deque<Eigen::Vector2d> shifts_;  // lens shift at clock_s_ - (size - 1 - j) * step_s_
  int resets_ = 0;
};

}  // namespace deep_ois
