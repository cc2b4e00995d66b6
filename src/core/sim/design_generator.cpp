#include "deep_ois/core/sim/design_generator.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <random>
#include <stdexcept>
#include <string>

#include "deep_ois/core/common/portable_random.h"

namespace deep_ois {
namespace sim {

namespace {

// Draws from the stated ranges (designParameterRanges()), so that what is drawn, validated and
// documented is one table.
class Draw {
 public:
  Draw(std::uint32_t seed, std::uint32_t stage) : rng_(streamGenerator(seed, stage)) {}
  double uniform(const char* name) {
    const DesignParameterRange& r = designParameterRange(name);
    return deep_ois::uniform(rng_, r.min, r.max);
  }
  // For corners and bandwidths: equally likely per octave.
  double logUniform(const char* name) {
    const DesignParameterRange& r = designParameterRange(name);
    return r.min * std::pow(r.max / r.min, uniform01(rng_));
  }
  int integer(const char* name) {
    const DesignParameterRange& r = designParameterRange(name);
    const int lo = static_cast<int>(r.min), hi = static_cast<int>(r.max);
    return std::min(hi, lo + static_cast<int>(uniform01(rng_) * (hi - lo + 1)));
  }
  bool chance(double p) { return uniform01(rng_) < p; }
  // Index of the first cumulative probability above a uniform draw.
  int pick(std::initializer_list<double> probabilities) {
    const double u = uniform01(rng_);
    double cumulative = 0.0;
    int i = 0;
    for (double p : probabilities) {
      cumulative += p;
      if (u < cumulative) return i;
      ++i;
    }
    return i - 1;
  }

 private:
  std::mt19937 rng_;
};

// One random stream per stage.
enum Stream : std::uint32_t {
  kMountStream = 1, kLoopStream, kEstimatorStream, kModeStream, kGainStream, kStrokeStream,
  kAntiWindupStream, kOutputStream, kActuatorStream, kHallStream,
};

}  // namespace

DesignSplit designSplit(std::uint32_t seed) {
  return seed % 5 == 0 ? DesignSplit::kHeldOut : DesignSplit::kTraining;
}

const char* toString(DesignSplit split) {
  return split == DesignSplit::kHeldOut ? "held_out" : "training";
}

StabiliserDesign generateDesign(std::uint32_t seed) {
  StabiliserDesign d;
  d.seed = seed;
  {
    Draw draw(seed, kMountStream);
    if (draw.chance(0.5)) {
      d.mount.roll_deg = draw.uniform("mount.roll_deg");
      d.mount.tilt_deg = draw.uniform("mount.tilt_deg");
      d.mount.pan_deg = draw.uniform("mount.pan_deg");
    }
    d.mount.noise_rad_s = draw.uniform("mount.noise_rad_s");
  }
  {
    Draw draw(seed, kLoopStream);
    const double rates[] = {4000.0, 2000.0, 1000.0, 500.0};
    d.loop.rate_hz = rates[draw.pick({0.4, 0.2, 0.2, 0.2})];
    d.loop.sampling = draw.chance(0.5) ? GyroSampling::kLatest : GyroSampling::kAveraged;
  }
  {
    Draw draw(seed, kEstimatorStream);
    d.estimator.kind = static_cast<EstimatorKind>(draw.pick({0.2, 0.2, 0.2, 0.2, 0.2}));
    d.estimator.corner_hz = draw.logUniform("estimator.corner_hz");
    d.estimator.damping = draw.uniform("estimator.damping");
    d.estimator.rate_corner_hz = draw.logUniform("estimator.rate_corner_hz");
    if (draw.chance(0.35)) {
      d.estimator.excursion_gain = draw.uniform("estimator.excursion_gain");
      d.estimator.excursion_power = draw.uniform("estimator.excursion_power");
    }
  }
  {
    Draw draw(seed, kModeStream);
    d.mode.action = static_cast<ModeAction>(draw.pick({0.5, 0.25, 0.25}));
    d.mode.threshold_rad_s = draw.uniform("mode.threshold_rad_s");
    d.mode.time_constant_s = draw.uniform("mode.time_constant_s");
    d.mode.release_factor = draw.uniform("mode.release_factor");
    d.mode.hold_time_constant_s = draw.uniform("mode.hold_time_constant_s");
  }
  {
    Draw draw(seed, kGainStream);
    d.gain.gain_x = draw.uniform("gain.gain_x");
    d.gain.gain_y = draw.chance(0.6) ? d.gain.gain_x : draw.uniform("gain.gain_y");
    if (draw.chance(0.3)) {
      d.gain.schedule_depth = draw.uniform("gain.schedule_depth");
      d.gain.schedule_start_rad_s = draw.uniform("gain.schedule_start_rad_s");
      d.gain.schedule_span_rad_s = draw.uniform("gain.schedule_span_rad_s");
      d.gain.schedule_time_constant_s = draw.uniform("gain.schedule_time_constant_s");
    }
  }
  {
    Draw draw(seed, kStrokeStream);
    d.stroke.kind = static_cast<StrokeKind>(draw.pick({0.25, 0.25, 0.25, 0.25}));
    const int symmetry = draw.pick({0.5, 0.25, 0.25});
    d.stroke.x_positive_deg = draw.uniform("stroke.x_positive_deg");
    d.stroke.x_negative_deg = d.stroke.x_positive_deg;
    d.stroke.y_positive_deg = d.stroke.x_positive_deg;
    d.stroke.y_negative_deg = d.stroke.x_positive_deg;
    if (symmetry >= 1) {  // x and y differ
      d.stroke.y_positive_deg = draw.uniform("stroke.y_positive_deg");
      d.stroke.y_negative_deg = d.stroke.y_positive_deg;
    }
    if (symmetry == 2) {  // and each direction its own
      d.stroke.x_negative_deg = draw.uniform("stroke.x_negative_deg");
      d.stroke.y_negative_deg = draw.uniform("stroke.y_negative_deg");
    }
  }
  {
    Draw draw(seed, kAntiWindupStream);
    d.anti_windup.kind = static_cast<AntiWindupKind>(draw.pick({1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0}));
    d.anti_windup.back_calculation_rate_per_s = draw.logUniform("anti_windup.back_calculation_rate_per_s");
  }
  {
    Draw draw(seed, kOutputStream);
    if (draw.chance(0.4)) d.output.quantiser_bits = draw.integer("output.quantiser_bits");
    if (draw.chance(0.4)) d.output.delay_s = draw.uniform("output.delay_s");
  }
  {
    Draw draw(seed, kActuatorStream);
    d.actuator.order = draw.chance(0.35) ? ActuatorOrder::kFirst : ActuatorOrder::kSecond;
    d.actuator.bandwidth_hz = draw.logUniform("actuator.bandwidth_hz");
    d.actuator.damping = draw.uniform("actuator.damping");
    if (draw.chance(0.3)) d.actuator.rate_limit_deg_s = draw.uniform("actuator.rate_limit_deg_s");
    if (draw.chance(0.3)) d.actuator.stiction_fraction = draw.uniform("actuator.stiction_fraction");
    d.actuator.end_stop_margin = draw.uniform("actuator.end_stop_margin");
  }
  {
    Draw draw(seed, kHallStream);
    if (draw.chance(0.5)) {
      d.hall.c2 = draw.uniform("hall.c2");
      d.hall.c3 = draw.uniform("hall.c3");
    }
    if (draw.chance(0.5)) d.hall.noise_px = draw.uniform("hall.noise_px");
  }
  const std::string problem = d.validate();
  if (!problem.empty()) {
    throw std::logic_error("generateDesign(" + std::to_string(seed) + ") drew an invalid design: " + problem);
  }
  return d;
}

}  // namespace sim
}  // namespace deep_ois
