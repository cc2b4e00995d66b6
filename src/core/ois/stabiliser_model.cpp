#include "deep_ois/core/ois/stabiliser_model.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/uniform_grid_interpolation.h"
#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {

StabiliserModel::StabiliserModel() {
  for (const StabiliserStage& stage : stabiliserStages())
    if (stage.in_default_chain) stages_.push_back({&stage, stage.make()});
}

StabiliserModel::StabiliserModel(const std::vector<std::string>& stage_names) {
  for (const std::string& name : stage_names) stabiliserStage(stageOfToken(name));  // known names
  for (const StabiliserStage& stage : stabiliserStages())
    for (const std::string& name : stage_names)
      if (stageOfToken(name) == stage.name) {
        stages_.push_back({&stage, stage.make()});
        break;
      }
}

StabiliserModel::StabiliserModel(const StabiliserModel& other) { *this = other; }

StabiliserModel& StabiliserModel::operator=(const StabiliserModel& other) {
  if (this == &other) return *this;
  std::vector<StageInstance> copied;
  copied.reserve(other.stages_.size());
  for (const StageInstance& instance : other.stages_)
    copied.push_back({instance.stage, instance.values->clone()});
  stages_ = std::move(copied);
  return *this;
}

std::vector<std::string> StabiliserModel::stageNames() const {
  std::vector<std::string> names;
  for (const StageInstance& instance : stages_) names.push_back(instance.stage->name);
  return names;
}

bool StabiliserModel::hasDefaultChain() const {
  for (const StabiliserStage& stage : stabiliserStages())
    if (stage.in_default_chain && !has(stage.name)) return false;
  return true;
}

const StageValues* StabiliserModel::values(const std::string& stage) const {
  for (const StageInstance& instance : stages_)
    if (stage == instance.stage->name) return instance.values.get();
  return nullptr;
}

StageValues* StabiliserModel::values(const std::string& stage) {
  return const_cast<StageValues*>(static_cast<const StabiliserModel*>(this)->values(stage));
}

const StageValues& StabiliserModel::required(const char* stage) const {
  const StageValues* found = values(stage);
  if (!found) throw std::logic_error(std::string("the stabiliser model has no stage '") + stage + "'");
  return *found;
}

StageValues& StabiliserModel::required(const char* stage) {
  return const_cast<StageValues&>(static_cast<const StabiliserModel*>(this)->required(stage));
}

StageValues& StabiliserModel::put(const std::string& stage, std::unique_ptr<StageValues> values) {
  if (StageValues* present = this->values(stage)) {
    for (StageInstance& instance : stages_)
      if (instance.values.get() == present) instance.values = std::move(values);
    return *this->values(stage);
  }
  // In the chain's order: before the first stage the model has that comes after it.
  const StabiliserStage& described = stabiliserStage(stage);
  auto at = stages_.begin();
  for (const StabiliserStage& each : stabiliserStages()) {
    if (&each == &described) break;
    if (at != stages_.end() && at->stage == &each) ++at;
  }
  return *stages_.insert(at, StageInstance{&described, std::move(values)})->values;
}

void StabiliserModel::remove(const std::string& stage) {
  stages_.erase(std::remove_if(stages_.begin(), stages_.end(),
                               [&](const StageInstance& instance) { return stage == instance.stage->name; }),
                stages_.end());
}

StabiliserModel StabiliserModel::only(const std::vector<std::string>& stage_names) const {
  StabiliserModel kept(stage_names);
  for (StageInstance& instance : kept.stages_)
    if (const StageValues* own = values(instance.stage->name)) instance.values = own->clone();
  return kept;
}

std::string StabiliserModel::validate() const {
  // Each stage validates its own values (core/ois/stabiliser_stage.h); the first problem, in the
  // chain's order, is the answer.
  for (const StageInstance& instance : stages_) {
    const std::string problem = instance.stage->validate(*instance.values, *this);
    if (!problem.empty()) return problem;
  }
  return {};
}

LensShiftPredictor::LensShiftPredictor(const StabiliserModel& model, double focal_px,
                                       double step_s, double history_s)
    : step_s_(step_s) {
  const std::string problem = model.validate();
  if (!problem.empty()) throw std::invalid_argument("stabiliser model: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px) || !(step_s > 0.0) || !(history_s > step_s)) {
    throw std::invalid_argument(
        "stabiliser model: focal_px and step_s must be positive and history_s > step_s");
  }
  history_steps_ = static_cast<std::size_t>(std::ceil(history_s / step_s)) + 2;
  chain_ = StabiliserChain(stabiliserRunners(model, {focal_px, step_s}));
  reset();
  resets_ = 0;
}

void LensShiftPredictor::reset() {
  started_ = false;
  chain_.reset();
  shifts_.clear();
  ++resets_;
}

bool LensShiftPredictor::addRate(const CameraRateSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.rate_rad_s.allFinite()) return false;
  // A jump back further than a gap (a replayed bag looping, a clock reset): the history no
  // longer leads to this sample, start over from it. A smaller step back is a stray sample.
  if (started_ && sample.stamp_s < last_stamp_s_ - max_gap_s) reset();
  if (started_ && !(sample.stamp_s > last_stamp_s_)) return false;
  if (started_ && sample.stamp_s - last_stamp_s_ > max_gap_s) reset();
  if (!started_) {
    started_ = true;
    last_stamp_s_ = sample.stamp_s;
    last_rate_ = sample.rate_rad_s;
    start_s_ = sample.stamp_s;
    steps_ = 0;
    clock_s_ = sample.stamp_s;
    shifts_.push_back(Eigen::Vector2d::Zero());
    return true;
  }
  // Internal steps up to the new sample, the rate interpolated at each step's middle.
  const double span = sample.stamp_s - last_stamp_s_;
  while (clock_s_ + step_s_ <= sample.stamp_s + 1e-12) {
    const double middle = clock_s_ + 0.5 * step_s_;
    const double alpha = std::clamp((middle - last_stamp_s_) / span, 0.0, 1.0);
    const double end_alpha = std::clamp((clock_s_ + step_s_ - last_stamp_s_) / span, 0.0, 1.0);
    step((1.0 - alpha) * last_rate_ + alpha * sample.rate_rad_s,
         (1.0 - end_alpha) * last_rate_ + end_alpha * sample.rate_rad_s);
  }
  last_stamp_s_ = sample.stamp_s;
  last_rate_ = sample.rate_rad_s;
  return true;
}

void LensShiftPredictor::step(const Eigen::Vector3d& rate_rad_s,
                              const Eigen::Vector3d& end_rate_rad_s) {
  shifts_.push_back(chain_.step(rate_rad_s, end_rate_rad_s));
  ++steps_;
  // From an integer step count: summing step_s_ on epoch-sized stamps would drift (ulp ~ 2e-7 s).
  clock_s_ = start_s_ + static_cast<double>(steps_) * step_s_;
  while (shifts_.size() > history_steps_) shifts_.pop_front();
}

bool LensShiftPredictor::covers(double t_s) const {
  if (shifts_.empty()) return false;
  const double oldest = clock_s_ - static_cast<double>(shifts_.size() - 1) * step_s_;
  // Up to the newest sample: after the last whole step (less than one step) the lens is held.
  return t_s >= oldest - 1e-9 && t_s <= last_stamp_s_ + 1e-9;
}

Eigen::Vector2d LensShiftPredictor::lensShiftAt(double t_s) const {
  if (shifts_.empty()) return Eigen::Vector2d::Zero();
  const double last = static_cast<double>(shifts_.size() - 1);
  return interpolateOnUniformGrid(shifts_, last - (clock_s_ - t_s) / step_s_);
}

}  // namespace deep_ois
