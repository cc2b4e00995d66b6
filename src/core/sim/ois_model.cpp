#include "deep_ois/core/sim/ois_model.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/sim/design_generator.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
// The actuator's resonance must be well resolved by the control loop.
constexpr double kMinControlStepsPerActuatorPeriod = 4.0;

// Reads "t_s,x_px,y_px" rows after a header line. Throws std::runtime_error naming file and line.
std::vector<std::pair<double, Eigen::Vector2d>> readLensShiftCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the lens shift CSV");
  std::vector<std::pair<double, Eigen::Vector2d>> rows;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1 || line.empty() || line[0] == '#') continue;  // header, comments
    std::istringstream fields(line);
    double t = 0.0, x = 0.0, y = 0.0;
    char comma1 = 0, comma2 = 0;
    if (!(fields >> t >> comma1 >> x >> comma2 >> y) || comma1 != ',' || comma2 != ',' ||
        !std::isfinite(t) || !std::isfinite(x) || !std::isfinite(y)) {
      throw std::runtime_error(path + ":" + std::to_string(number) +
                               ": expected 't_s,x_px,y_px' with finite numbers");
    }
    if (!rows.empty() && !(t > rows.back().first)) {
      throw std::runtime_error(path + ":" + std::to_string(number) + ": times must increase");
    }
    rows.push_back({t, Eigen::Vector2d(x, y)});
  }
  if (rows.empty()) throw std::runtime_error(path + ": no lens shift rows");
  return rows;
}

// Linear interpolation of the CSV trajectory at time t, held outside it.
Eigen::Vector2d interpolate(const std::vector<std::pair<double, Eigen::Vector2d>>& rows, double t) {
  if (t <= rows.front().first) return rows.front().second;
  if (t >= rows.back().first) return rows.back().second;
  const auto after = std::upper_bound(rows.begin(), rows.end(), t,
                                      [](double value, const auto& row) { return value < row.first; });
  const auto before = after - 1;
  const double alpha = (t - before->first) / (after->first - before->first);
  return (1.0 - alpha) * before->second + alpha * after->second;
}

}  // namespace

const char* toString(StrokeShape shape) { return shape == StrokeShape::kBox ? "box" : "circle"; }

bool parseStrokeShape(const std::string& text, StrokeShape* shape) {
  if (text == "box") *shape = StrokeShape::kBox;
  else if (text == "circle") *shape = StrokeShape::kCircle;
  else return false;
  return true;
}

std::string OisConfig::validate() const {
  std::ostringstream why;
  auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
  if (!std::isfinite(highpass_corner_hz) || highpass_corner_hz < 0.0) {
    why << "highpass_corner_hz: must be non-negative, 0 = no centring (got " << highpass_corner_hz
        << " Hz)";
  } else if (!positive(actuator_natural_hz)) {
    why << "actuator_natural_hz: must be positive (got " << actuator_natural_hz << " Hz)";
  } else if (!positive(actuator_damping)) {
    why << "actuator_damping: must be positive (got " << actuator_damping << ")";
  } else if (!(stroke_limit_deg > 0.0 && stroke_limit_deg < 45.0)) {
    why << "stroke_limit_deg: must be in (0, 45) degrees (got " << stroke_limit_deg << ")";
  } else if (!(gain >= 0.0 && gain <= 2.0)) {
    why << "gain: must be in [0, 2] (got " << gain << ")";
  } else if (!std::isfinite(gyro_noise_rad_s) || gyro_noise_rad_s < 0.0) {
    why << "gyro_noise_rad_s: must be non-negative (got " << gyro_noise_rad_s << ")";
  } else if (!std::isfinite(stroke_limit_y_deg) || stroke_limit_y_deg < 0.0 ||
             stroke_limit_y_deg >= 45.0) {
    why << "stroke_limit_y_deg: must be in [0, 45) degrees, 0 = as stroke_limit_deg (got "
        << stroke_limit_y_deg << ")";
  } else if (!std::isfinite(pan_detection_rate_rad_s) || pan_detection_rate_rad_s < 0.0) {
    why << "pan_detection_rate_rad_s: must be non-negative, 0 = off (got "
        << pan_detection_rate_rad_s << ")";
  } else if (!positive(pan_detection_time_constant_s)) {
    why << "pan_detection_time_constant_s: must be positive (got "
        << pan_detection_time_constant_s << " s)";
  } else if (!positive(pan_release_corner_hz)) {
    why << "pan_release_corner_hz: must be positive (got " << pan_release_corner_hz << " Hz)";
  } else if (!std::isfinite(hall_noise_px) || hall_noise_px < 0.0) {
    why << "hall_noise_px: must be non-negative (got " << hall_noise_px << ")";
  } else if (position_loop != "second_order" && position_loop != "pi") {
    why << "position_loop: must be second_order or pi (got '" << position_loop << "')";
  } else if (position_loop == "pi" &&
             (!positive(pi_plant_natural_hz) || !positive(pi_plant_damping) || !positive(pi_kp) ||
              !std::isfinite(pi_ki) || pi_ki < 0.0)) {
    why << "pi_plant_natural_hz, pi_plant_damping, pi_kp: must be positive, pi_ki >= 0";
  } else if (position_loop == "pi" && !(control_rate_hz >= 20.0 * pi_plant_natural_hz * std::sqrt(1.0 + pi_kp))) {
    why << "control_rate_hz: a pi position loop needs at least 20 x its closed-loop frequency";
  } else if (controller != "highpass" && controller != "kalman") {
    why << "controller: must be highpass or kalman (got '" << controller << "')";
  } else if (controller == "kalman" && !positive(kalman_bandwidth_hz)) {
    why << "kalman_bandwidth_hz: must be positive (got " << kalman_bandwidth_hz << " Hz)";
  } else if (!std::isfinite(kalman_manoeuvre_deg) || kalman_manoeuvre_deg < 0.0 ||
             !(kalman_manoeuvre_factor >= 1.0) || !std::isfinite(kalman_manoeuvre_factor)) {
    why << "kalman_manoeuvre_deg: must be >= 0 degrees (0 = off) and kalman_manoeuvre_factor >= 1";
  } else if (!std::isfinite(excursion_recentring_gain) || excursion_recentring_gain < 0.0 ||
             !positive(excursion_recentring_power)) {
    why << "excursion_recentring_gain: must be >= 0 (0 = off), excursion_recentring_power > 0";
  } else if (!std::isfinite(digital_rate_hz) || digital_rate_hz < 0.0 ||
             digital_rate_hz > control_rate_hz) {
    why << "digital_rate_hz: must be in [0, control_rate_hz], 0 = continuous (got "
        << digital_rate_hz << " Hz)";
  } else if (!std::isfinite(digital_delay_s) || digital_delay_s < 0.0 || digital_delay_s > 0.05) {
    why << "digital_delay_s: must be in [0, 0.05] s (got " << digital_delay_s << ")";
  } else if (!std::isfinite(command_lsb_deg) || command_lsb_deg < 0.0 || command_lsb_deg > 0.5) {
    why << "command_lsb_deg: must be in [0, 0.5] degrees, 0 = not quantised (got "
        << command_lsb_deg << ")";
  } else if (!std::isfinite(mount_rotation_deg) || std::abs(mount_rotation_deg) > 45.0) {
    why << "mount_rotation_deg: must be within +-45 degrees (got " << mount_rotation_deg << ")";
  } else if (!std::isfinite(actuator_cross_coupling) || std::abs(actuator_cross_coupling) > 0.5) {
    why << "actuator_cross_coupling: must be within +-0.5 (got " << actuator_cross_coupling << ")";
  } else if (!std::isfinite(hall_lag_s) || hall_lag_s < 0.0 || hall_lag_s > 0.1) {
    why << "hall_lag_s: must be in [0, 0.1] s (got " << hall_lag_s << ")";
  } else if (design_seed < -1 || design_seed > 4294967295LL) {
    why << "design_seed: must be a generated design's seed, 0..4294967295, or -1 for none (got "
        << design_seed << ")";
  } else if (design_seed >= 0 && !lens_shift_csv.empty()) {
    why << "design_seed: a generated design and lens_shift_csv exclude each other";
  } else if (!positive(control_rate_hz) ||
             control_rate_hz < kMinControlStepsPerActuatorPeriod * actuator_natural_hz) {
    why << "control_rate_hz: must be at least " << kMinControlStepsPerActuatorPeriod
        << " x actuator_natural_hz (got " << control_rate_hz << " Hz)";
  }
  return why.str();
}


// Sign of the cancelling shift, in the optical frame (x right, y down, z forward) and with
// rotationHomography(K, R_b_a) = K R_b_a K^-1, R_b_a = R_b^T R_a (camera a -> camera b):
//  - the camera turns by +theta about its own y axis: R_b = R_a exp(theta [e_y]x), so
//    R_b_a = Ry(-theta) and the centre ray (0, 0, 1) of frame a becomes (-sin, 0, cos) in frame
//    b: the image centre moves by -f tan(theta) in x; the lens must add +f tan(theta_y) in x;
//  - about +x: R_b_a = Rx(-theta) maps (0, 0, 1) to (0, sin, cos): the centre moves by
//    +f tan(theta) in y; the lens must add -f tan(theta_x) in y.
// Hence s_cmd = gain * f * (tan(theta_y), -tan(theta_x)) for a shift that moves image points by
// +s. For a rotation about one axis this cancels the image motion of the direction that was at
// the centre when the (high-passed) angle was zero exactly; test_ois_model checks it against
// rotationHomography. Roll (about z) moves the centre nowhere and is not integrated.
//
// The stabilizer integrates each axis' rate on its own (as real OIS controllers do): for the
// small angles of a shake the difference to composing rotations is second order. The centring
// high-pass on the integrated angle, theta_hp = s / (s + wc) * theta with theta' = w, is the
// leaky integrator theta_hp' = w - wc theta_hp, discretised exactly for the mean rate of a step.
OisModel::OisModel(const OisConfig& config, const CameraMotion& motion, double focal_px,
                   std::uint32_t seed)
    : config_(config), start_s_(motion.startTime()) {
  const std::string problem = config_.validate();
  if (!problem.empty()) throw std::invalid_argument("ois: " + problem);
  if (!(focal_px > 0.0) || !std::isfinite(focal_px)) {
    std::ostringstream why;
    why << "ois: focal_px must be positive (got " << focal_px << ")";
    throw std::invalid_argument(why.str());
  }
  stroke_limit_px_ = focal_px * std::tan(config_.stroke_limit_deg * kPi / 180.0);
  const double limit_y_deg =
      config_.stroke_limit_y_deg > 0.0 ? config_.stroke_limit_y_deg : config_.stroke_limit_deg;
  stroke_limit_y_px_ = focal_px * std::tan(limit_y_deg * kPi / 180.0);
  if (config_.design_seed >= 0) {
    // A generated design: its own stroke (the larger direction per axis) and its own chain.
    const StabiliserDesign design = generateDesign(static_cast<std::uint32_t>(config_.design_seed));
    stroke_limit_px_ = focal_px * std::tan(std::max(design.stroke.x_positive_deg,
                                                    design.stroke.x_negative_deg) * kPi / 180.0);
    stroke_limit_y_px_ = focal_px * std::tan(std::max(design.stroke.y_positive_deg,
                                                      design.stroke.y_negative_deg) * kPi / 180.0);
    if (!config_.enabled) return;
    const int steps = std::max(
        1, static_cast<int>(std::ceil((motion.endTime() - start_s_) * kDesignPhysicsRateHz)));
    std::mt19937 rng(seed);
    grid_ = runDesign(design, focal_px, start_s_, steps,
                      [&motion](double t_s) { return motion.angularVelocity(t_s); }, &rng);
    return;
  }
  if (!config_.enabled) return;

  const double dt = 1.0 / config_.control_rate_hz;
  const int steps = std::max(
      1, static_cast<int>(std::ceil((motion.endTime() - start_s_) * config_.control_rate_hz)));
  if (!config_.lens_shift_csv.empty()) {
    // A logged trajectory instead of the stabiliser: the same seed's motion, another lens.
    const auto rows = readLensShiftCsv(config_.lens_shift_csv);
    std::vector<Eigen::Vector2d> shifts(steps + 1, Eigen::Vector2d::Zero());
    for (int j = 0; j <= steps; ++j) shifts[j] = interpolate(rows, j * dt);
    grid_ = LensShiftGrid(start_s_, config_.control_rate_hz, std::move(shifts));
    return;
  }

  // The stabiliser on the true motion, with its own gyro's and Hall sensor's noise.
  std::mt19937 rng(seed);
  grid_ = runStabiliser(config_, focal_px, start_s_, steps,
                        [&motion](double t_s) { return motion.angularVelocity(t_s); }, &rng);
}

Eigen::Vector2d OisModel::lensShift(double t_s) const { return grid_.at(t_s); }

}  // namespace sim
}  // namespace deep_ois
