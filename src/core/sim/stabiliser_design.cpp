#include "deep_ois/core/sim/stabiliser_design.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

}  // namespace

Eigen::Matrix3d GyroMountStage::cameraToGyro() const {
  // Roll about the optical axis first, then the small tilt (x) and pan (y) errors of the die.
  return (Eigen::AngleAxisd(pan_deg * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(tilt_deg * kDeg, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix()
      .transpose();
}

bool StrokeStage::asymmetric() const {
  return x_positive_deg != x_negative_deg || y_positive_deg != y_negative_deg ||
         x_positive_deg != y_positive_deg;
}

const std::vector<DesignParameterRange>& designParameterRanges() {
  // DESIGN.md's physics: centring corners 0.1-2 Hz, actuator bandwidth tens of Hz to ~100 Hz,
  // stroke +-0.5 to +-1.5 deg. The others from what phone modules and their datasheets show.
  static const std::vector<DesignParameterRange> ranges = {
      {"mount.roll_deg", -15.0, 15.0, "deg", "gyro die turned about the optical axis"},
      {"mount.tilt_deg", -3.0, 3.0, "deg", "gyro die tilted about camera x"},
      {"mount.pan_deg", -3.0, 3.0, "deg", "gyro die tilted about camera y"},
      {"mount.noise_rad_s", 0.0, 0.004, "rad/s", "stabiliser gyro white noise per step"},
      {"loop.rate_hz", 500.0, 4000.0, "Hz", "controller rate (4000 = continuous)"},
      {"estimator.corner_hz", 0.1, 2.0, "Hz", "centring corner / estimator bandwidth"},
      {"estimator.damping", 0.5, 1.2, "", "second-order centring, alpha-beta damping"},
      {"estimator.rate_corner_hz", 0.1, 1.5, "Hz", "velocity loop: rate high-pass corner"},
      {"estimator.excursion_gain", 2.0, 12.0, "", "excursion centring: corner x (1 + gain e^p)"},
      {"estimator.excursion_power", 1.0, 4.0, "", "excursion centring: power p"},
      {"mode.threshold_rad_s", 0.15, 0.5, "rad/s", "pan detected above this sustained rate"},
      {"mode.time_constant_s", 0.1, 0.5, "s", "low-pass of the rate vector it decides on"},
      {"mode.release_factor", 3.0, 15.0, "", "corner multiplier while panning"},
      {"mode.hold_time_constant_s", 0.05, 0.3, "s", "gain ramp to 0 and back"},
      {"gain.gain_x", 0.85, 1.1, "", "fraction of the rotation cancelled, lens x"},
      {"gain.gain_y", 0.85, 1.1, "", "fraction of the rotation cancelled, lens y"},
      {"gain.schedule_depth", 0.2, 0.7, "", "gain lost at high motion"},
      {"gain.schedule_start_rad_s", 0.05, 0.25, "rad/s", "motion where the gain starts to fall"},
      {"gain.schedule_span_rad_s", 0.1, 0.5, "rad/s", "motion over which it falls"},
      {"gain.schedule_time_constant_s", 0.05, 0.3, "s", "low-pass of the scheduling motion"},
      {"stroke.x_positive_deg", 0.5, 1.5, "deg", "travel, +x"},
      {"stroke.x_negative_deg", 0.5, 1.5, "deg", "travel, -x"},
      {"stroke.y_positive_deg", 0.5, 1.5, "deg", "travel, +y"},
      {"stroke.y_negative_deg", 0.5, 1.5, "deg", "travel, -y"},
      {"anti_windup.back_calculation_rate_per_s", 5.0, 50.0, "1/s", "back-calculation rate"},
      {"output.quantiser_bits", 7.0, 12.0, "bits", "DAC resolution over the x stroke"},
      {"output.delay_s", 0.0005, 0.006, "s", "transport delay of the command"},
      {"actuator.bandwidth_hz", 20.0, 120.0, "Hz", "corner (1st order) / natural (2nd order)"},
      {"actuator.damping", 0.4, 1.0, "", "second-order damping"},
      {"actuator.rate_limit_deg_s", 25.0, 100.0, "deg/s", "lens slew limit"},
      {"actuator.stiction_fraction", 0.005, 0.03, "", "breakaway error / x stroke"},
      {"actuator.end_stop_margin", 1.0, 1.3, "", "mechanical end stop / stroke"},
      {"hall.c2", -0.05, 0.05, "", "Hall reading's even (quadratic) term"},
      {"hall.c3", -0.15, 0.15, "", "Hall reading's odd (cubic) term"},
      {"hall.noise_px", 0.0, 0.03, "px", "Hall reading's white noise"},
  };
  return ranges;
}

const DesignParameterRange& designParameterRange(const std::string& name) {
  for (const DesignParameterRange& range : designParameterRanges()) {
    if (name == range.name) return range;
  }
  throw std::out_of_range("no design parameter range called '" + name + "'");
}

std::vector<std::pair<std::string, double>> designParameters(const StabiliserDesign& d) {
  std::vector<std::pair<std::string, double>> p = {
      {"mount.roll_deg", d.mount.roll_deg},
      {"mount.tilt_deg", d.mount.tilt_deg},
      {"mount.pan_deg", d.mount.pan_deg},
      {"mount.noise_rad_s", d.mount.noise_rad_s},
      {"loop.rate_hz", d.loop.rate_hz},
      {"estimator.corner_hz", d.estimator.corner_hz},
  };
  const EstimatorKind kind = d.estimator.kind;
  if (kind == EstimatorKind::kHighpass2 || kind == EstimatorKind::kAlphaBeta) {
    p.push_back({"estimator.damping", d.estimator.damping});
  }
  if (kind == EstimatorKind::kVelocityLoop) {
    p.push_back({"estimator.rate_corner_hz", d.estimator.rate_corner_hz});
  }
  if (d.estimator.excursion_gain != 0.0) {
    p.push_back({"estimator.excursion_gain", d.estimator.excursion_gain});
    p.push_back({"estimator.excursion_power", d.estimator.excursion_power});
  }
  if (d.mode.action != ModeAction::kNone) {
    p.push_back({"mode.threshold_rad_s", d.mode.threshold_rad_s});
    p.push_back({"mode.time_constant_s", d.mode.time_constant_s});
    if (d.mode.action == ModeAction::kRelease) {
      p.push_back({"mode.release_factor", d.mode.release_factor});
    } else {
      p.push_back({"mode.hold_time_constant_s", d.mode.hold_time_constant_s});
    }
  }
  p.push_back({"gain.gain_x", d.gain.gain_x});
  p.push_back({"gain.gain_y", d.gain.gain_y});
  if (d.gain.schedule_depth != 0.0) {
    p.push_back({"gain.schedule_depth", d.gain.schedule_depth});
    p.push_back({"gain.schedule_start_rad_s", d.gain.schedule_start_rad_s});
    p.push_back({"gain.schedule_span_rad_s", d.gain.schedule_span_rad_s});
    p.push_back({"gain.schedule_time_constant_s", d.gain.schedule_time_constant_s});
  }
  p.push_back({"stroke.x_positive_deg", d.stroke.x_positive_deg});
  p.push_back({"stroke.x_negative_deg", d.stroke.x_negative_deg});
  p.push_back({"stroke.y_positive_deg", d.stroke.y_positive_deg});
  p.push_back({"stroke.y_negative_deg", d.stroke.y_negative_deg});
  if (d.anti_windup.kind == AntiWindupKind::kBackCalculation) {
    p.push_back({"anti_windup.back_calculation_rate_per_s", d.anti_windup.back_calculation_rate_per_s});
  }
  if (d.output.quantiser_bits != 0) {
    p.push_back({"output.quantiser_bits", static_cast<double>(d.output.quantiser_bits)});
  }
  if (d.output.delay_s != 0.0) p.push_back({"output.delay_s", d.output.delay_s});
  p.push_back({"actuator.bandwidth_hz", d.actuator.bandwidth_hz});
  if (d.actuator.order == ActuatorOrder::kSecond) {
    p.push_back({"actuator.damping", d.actuator.damping});
  }
  if (d.actuator.rate_limit_deg_s != 0.0) {
    p.push_back({"actuator.rate_limit_deg_s", d.actuator.rate_limit_deg_s});
  }
  if (d.actuator.stiction_fraction != 0.0) {
    p.push_back({"actuator.stiction_fraction", d.actuator.stiction_fraction});
  }
  p.push_back({"actuator.end_stop_margin", d.actuator.end_stop_margin});
  p.push_back({"hall.c2", d.hall.c2});
  p.push_back({"hall.c3", d.hall.c3});
  p.push_back({"hall.noise_px", d.hall.noise_px});
  return p;
}

std::string StabiliserDesign::validate() const {
  for (const auto& [name, value] : designParameters(*this)) {
    const DesignParameterRange& range = designParameterRange(name);
    if (!std::isfinite(value) || value < range.min || value > range.max) {
      std::ostringstream why;
      why << name << ": must be in [" << range.min << ", " << range.max << "]"
          << (range.unit[0] ? " " : "") << range.unit << " (got " << value << ")";
      if (name.find("excursion") != std::string::npos || name.find("schedule") != std::string::npos) {
        why << "; 0 turns it off";
      }
      return why.str();
    }
  }
  const double steps_per_tick = kDesignPhysicsRateHz / loop.rate_hz;
  if (std::abs(steps_per_tick - std::round(steps_per_tick)) > 1e-9) {
    std::ostringstream why;
    why << "loop.rate_hz: must divide " << kDesignPhysicsRateHz << " Hz (got " << loop.rate_hz << ")";
    return why.str();
  }
  return {};
}

const char* toString(EstimatorKind kind) {
  switch (kind) {
    case EstimatorKind::kHighpass1: return "highpass_first_order";
    case EstimatorKind::kHighpass2: return "highpass_second_order";
    case EstimatorKind::kVelocityLoop: return "velocity_loop";
    case EstimatorKind::kKalman: return "kalman_cv";
    case EstimatorKind::kAlphaBeta: return "alpha_beta";
  }
  return "?";
}

const char* toString(StrokeKind kind) {
  switch (kind) {
    case StrokeKind::kBox: return "box";
    case StrokeKind::kEllipse: return "ellipse";
    case StrokeKind::kSoftBox: return "soft_box";
    case StrokeKind::kSoftEllipse: return "soft_ellipse";
  }
  return "?";
}

const char* toString(AntiWindupKind kind) {
  switch (kind) {
    case AntiWindupKind::kNone: return "none";
    case AntiWindupKind::kClamp: return "clamp";
    case AntiWindupKind::kBackCalculation: return "back_calculation";
  }
  return "?";
}

const char* toString(ModeAction action) {
  switch (action) {
    case ModeAction::kNone: return "none";
    case ModeAction::kRelease: return "release";
    case ModeAction::kHold: return "hold";
  }
  return "?";
}

const char* designClass(const StabiliserDesign& design) { return toString(design.estimator.kind); }

const std::vector<std::string>& designClasses() {
  static const std::vector<std::string> classes = {"highpass_first_order", "highpass_second_order",
                                                   "velocity_loop", "kalman_cv", "alpha_beta"};
  return classes;
}

std::vector<std::string> designFeatures(const StabiliserDesign& d) {
  std::vector<std::string> tags = {designClass(d)};
  tags.push_back(d.estimator.excursion_gain != 0.0 ? "centring_excursion" : "centring_fixed");
  if (d.mode.action != ModeAction::kNone) tags.push_back(std::string("mode_") + toString(d.mode.action));
  if (d.gain.schedule_depth != 0.0) tags.push_back("gain_scheduled");
  const bool ellipse = d.stroke.kind == StrokeKind::kEllipse || d.stroke.kind == StrokeKind::kSoftEllipse;
  tags.push_back(ellipse ? "stroke_ellipse" : "stroke_box");
  if (d.stroke.kind == StrokeKind::kSoftBox || d.stroke.kind == StrokeKind::kSoftEllipse) {
    tags.push_back("stroke_soft");
  }
  if (d.stroke.asymmetric()) tags.push_back("stroke_asymmetric");
  tags.push_back(std::string("anti_windup_") + toString(d.anti_windup.kind));
  tags.push_back(d.actuator.order == ActuatorOrder::kFirst ? "actuator_first_order"
                                                           : "actuator_second_order");
  if (d.actuator.rate_limit_deg_s != 0.0) tags.push_back("actuator_rate_limit");
  if (d.actuator.stiction_fraction != 0.0) tags.push_back("actuator_stiction");
  if (d.output.delay_s != 0.0) tags.push_back("transport_delay");
  if (d.loop.rate_hz < kDesignPhysicsRateHz) tags.push_back("digital_loop");
  if (d.output.quantiser_bits != 0) tags.push_back("quantised");
  if (d.mount.roll_deg != 0.0 || d.mount.tilt_deg != 0.0 || d.mount.pan_deg != 0.0) {
    tags.push_back("gyro_misaligned");
  }
  if (d.hall.c2 != 0.0 || d.hall.c3 != 0.0) tags.push_back("hall_nonlinear");
  return tags;
}

const std::vector<std::string>& designFeatureTags() {
  static const std::vector<std::string> tags = [] {
    std::vector<std::string> all = designClasses();
    for (const char* tag :
         {"centring_fixed", "centring_excursion", "mode_release", "mode_hold", "gain_scheduled",
          "stroke_box", "stroke_ellipse", "stroke_soft", "stroke_asymmetric", "anti_windup_none",
          "anti_windup_clamp", "anti_windup_back_calculation", "actuator_first_order",
          "actuator_second_order", "actuator_rate_limit", "actuator_stiction", "transport_delay",
          "digital_loop", "quantised", "gyro_misaligned", "hall_nonlinear"}) {
      all.push_back(tag);
    }
    return all;
  }();
  return tags;
}

std::string describe(const StabiliserDesign& d) {
  std::ostringstream out;
  out.precision(3);
  out << "design " << d.seed << " (" << designClass(d) << ")\n";
  out << "  mount: roll " << d.mount.roll_deg << " deg, tilt " << d.mount.tilt_deg << " deg, pan "
      << d.mount.pan_deg << " deg, gyro noise " << d.mount.noise_rad_s << " rad/s\n";
  out << "  loop: " << static_cast<int>(d.loop.rate_hz) << " Hz, "
      << (d.loop.sampling == GyroSampling::kLatest ? "latest sample" : "averaged") << "\n";
  out << "  estimator: " << toString(d.estimator.kind) << ", corner " << d.estimator.corner_hz << " Hz";
  if (d.estimator.kind == EstimatorKind::kHighpass2 || d.estimator.kind == EstimatorKind::kAlphaBeta) {
    out << ", damping " << d.estimator.damping;
  }
  if (d.estimator.kind == EstimatorKind::kVelocityLoop) {
    out << ", rate corner " << d.estimator.rate_corner_hz << " Hz";
  }
  if (d.estimator.excursion_gain != 0.0) {
    out << ", excursion centring x (1 + " << d.estimator.excursion_gain << " e^"
        << d.estimator.excursion_power << ")";
  }
  out << "\n  mode: " << toString(d.mode.action);
  if (d.mode.action != ModeAction::kNone) {
    out << " above " << d.mode.threshold_rad_s << " rad/s (tau " << d.mode.time_constant_s << " s), ";
    if (d.mode.action == ModeAction::kRelease) {
      out << "corner x " << d.mode.release_factor;
    } else {
      out << "gain ramp " << d.mode.hold_time_constant_s << " s";
    }
  }
  out << "\n  gain: x " << d.gain.gain_x << ", y " << d.gain.gain_y;
  if (d.gain.schedule_depth != 0.0) {
    out << ", scheduled -" << d.gain.schedule_depth << " over " << d.gain.schedule_start_rad_s
        << "-" << d.gain.schedule_start_rad_s + d.gain.schedule_span_rad_s << " rad/s";
  }
  out << "\n  stroke: " << toString(d.stroke.kind) << " x +" << d.stroke.x_positive_deg << "/-"
      << d.stroke.x_negative_deg << " deg, y +" << d.stroke.y_positive_deg << "/-"
      << d.stroke.y_negative_deg << " deg\n";
  out << "  anti-windup: " << toString(d.anti_windup.kind);
  if (d.anti_windup.kind == AntiWindupKind::kBackCalculation) {
    out << " at " << d.anti_windup.back_calculation_rate_per_s << " /s";
  }
  out << "\n  output: " << (d.output.quantiser_bits ? std::to_string(d.output.quantiser_bits) + "-bit"
                                                     : std::string("not quantised"))
      << ", delay " << d.output.delay_s * 1e3 << " ms\n";
  out << "  actuator: " << (d.actuator.order == ActuatorOrder::kFirst ? "first" : "second")
      << " order " << d.actuator.bandwidth_hz << " Hz";
  if (d.actuator.order == ActuatorOrder::kSecond) out << ", damping " << d.actuator.damping;
  if (d.actuator.rate_limit_deg_s != 0.0) out << ", slew " << d.actuator.rate_limit_deg_s << " deg/s";
  if (d.actuator.stiction_fraction != 0.0) {
    out << ", stiction " << d.actuator.stiction_fraction * 100.0 << " % of stroke";
  }
  out << ", end stop x " << d.actuator.end_stop_margin << "\n";
  out << "  hall: c2 " << d.hall.c2 << ", c3 " << d.hall.c3 << ", noise " << d.hall.noise_px << " px\n";
  return out.str();
}

}  // namespace sim
}  // namespace deep_ois
