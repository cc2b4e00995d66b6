#include "deep_ois/core/synthetic_rotation_sequence.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/orientation_integrator.h"

namespace deep_ois {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Uniform double in [0, 1) from two raw mt19937 outputs (53 bits), the same everywhere, unlike
// std::uniform_real_distribution whose algorithm each standard library picks.
double uniform01(std::mt19937& rng) {
  const std::uint64_t high = rng() >> 5;  // 27 bits
  const std::uint64_t low = rng() >> 6;   // 26 bits
  return (static_cast<double>(high) * 67108864.0 + static_cast<double>(low)) / 9007199254740992.0;
}

double uniform(std::mt19937& rng, double lo, double hi) { return lo + (hi - lo) * uniform01(rng); }

// Standard normal by Box-Muller on uniform01 (std::normal_distribution is not portable either).
double gaussian(std::mt19937& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0, 1]
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

Eigen::Vector3d uniformUnitVector(std::mt19937& rng) {
  const double z = uniform(rng, -1.0, 1.0);
  const double phi = uniform(rng, 0.0, 2.0 * kPi);
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
}

// Independent generators per purpose, so that e.g. changing the IMU rate leaves the scene alone.
std::mt19937 streamGenerator(std::uint32_t seed, std::uint32_t stream) {
  return std::mt19937(seed * 2654435761u + stream * 40503u + 12345u);
}

// 3-D value noise on an integer lattice: a seeded permutation table picks a value per lattice
// point, quintic fade between them. Range [0, 1].
class ValueNoise {
 public:
  explicit ValueNoise(std::mt19937& rng) {
    for (int i = 0; i < 256; ++i) perm_[i] = static_cast<std::uint8_t>(i);
    for (int i = 255; i > 0; --i) {  // Fisher-Yates with a fixed integer formula
      const int j = static_cast<int>(rng() % static_cast<std::uint32_t>(i + 1));
      std::swap(perm_[i], perm_[j]);
    }
    for (int i = 0; i < 256; ++i) {
      perm_[256 + i] = perm_[i];
      value_[i] = static_cast<float>(uniform01(rng));
    }
  }

  float operator()(double x, double y, double z) const {
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const int ix = static_cast<int>(fx) & 255, iy = static_cast<int>(fy) & 255,
              iz = static_cast<int>(fz) & 255;
    const float tx = fade(static_cast<float>(x - fx)), ty = fade(static_cast<float>(y - fy)),
                tz = fade(static_cast<float>(z - fz));
    auto at = [&](int dx, int dy, int dz) {
      return value_[perm_[perm_[perm_[ix + dx] + iy + dy] + iz + dz]];
    };
    const float x00 = lerp(at(0, 0, 0), at(1, 0, 0), tx), x10 = lerp(at(0, 1, 0), at(1, 1, 0), tx);
    const float x01 = lerp(at(0, 0, 1), at(1, 0, 1), tx), x11 = lerp(at(0, 1, 1), at(1, 1, 1), tx);
    return lerp(lerp(x00, x10, ty), lerp(x01, x11, ty), tz);
  }

  // Sum of `octaves` octaves from `frequency` (cycles per unit), amplitude halving; range [0, 1].
  float fractal(const Eigen::Vector3d& p, double frequency, int octaves) const {
    float sum = 0.0f, weight = 0.0f, amplitude = 1.0f;
    for (int o = 0; o < octaves; ++o) {
      // The offset decorrelates the octaves' lattices (all share the origin otherwise).
      sum += amplitude * (*this)(p.x() * frequency + 17.3 * o, p.y() * frequency + 5.1 * o,
                                 p.z() * frequency + 11.7 * o);
      weight += amplitude;
      amplitude *= 0.5f;
      frequency *= 2.0;
    }
    return sum / weight;
  }

 private:
  static float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
  static float lerp(float a, float b, float t) { return a + (b - a) * t; }

  std::uint8_t perm_[512];
  float value_[256];
};

float smoothstep(float edge0, float edge1, float x) {
  const float t = std::clamp((x - edge0) / (edge1 - edge0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

cv::Vec3f mix(const cv::Vec3f& a, const cv::Vec3f& b, float t) { return a + (b - a) * t; }

// A saturated colour of random hue and a mid-to-high value, from the HSV cone.
cv::Vec3f randomColour(std::mt19937& rng, double min_value, double max_value) {
  const double hue = uniform(rng, 0.0, 6.0);
  const double saturation = uniform(rng, 0.45, 1.0);
  const double value = uniform(rng, min_value, max_value);
  // HSV -> RGB: channel n is v - v s clamp(min(k, 4 - k), 0, 1) with k = (n + hue) mod 6.
  auto channel = [&](double n) {
    const double k = std::fmod(n + hue, 6.0);
    return static_cast<float>(value -
                              value * saturation * std::clamp(std::min(k, 4.0 - k), 0.0, 1.0));
  };
  return cv::Vec3f(channel(5.0), channel(3.0), channel(1.0));
}

// Cube face f: major axis f / 2, sign + for even f; face coordinates (u, v) = the next two
// axes (cyclically) divided by the major one, both in [-1, 1].
struct CubeLookup {
  int face;
  double u;
  double v;
};

inline CubeLookup cubeLookup(double x, double y, double z) {
  const double ax = std::abs(x), ay = std::abs(y), az = std::abs(z);
  if (ax >= ay && ax >= az) return {x >= 0 ? 0 : 1, y / ax, z / ax};
  if (ay >= az) return {y >= 0 ? 2 : 3, z / ay, x / ay};
  return {z >= 0 ? 4 : 5, x / az, y / az};
}

Eigen::Vector3d cubeDirection(int face, double u, double v) {
  const int axis = face / 2;
  Eigen::Vector3d d;
  d[axis] = face % 2 == 0 ? 1.0 : -1.0;
  d[(axis + 1) % 3] = u;
  d[(axis + 2) % 3] = v;
  return d;
}

// Bilinear RGB lookup, accumulated into `sum`. `half_edge` = face edge texels / 2; texel i of a
// bordered face has its centre at u = (i - 0.5) / half_edge - 1.
inline void accumulateCube(const std::vector<cv::Mat>& faces, double half_edge, double x, double y,
                           double z, float sum[3]) {
  const CubeLookup at = cubeLookup(x, y, z);
  const double fx = (at.u + 1.0) * half_edge + 0.5;  // >= 0.5, so truncation is floor
  const double fy = (at.v + 1.0) * half_edge + 0.5;
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const float wx = static_cast<float>(fx - x0), wy = static_cast<float>(fy - y0);
  const cv::Mat& face = faces[at.face];
  const std::uint8_t* top = face.ptr<std::uint8_t>(y0) + 3 * x0;
  const std::uint8_t* bottom = face.ptr<std::uint8_t>(y0 + 1) + 3 * x0;
  for (int c = 0; c < 3; ++c) {
    const float upper = top[c] + wx * (top[c + 3] - top[c]);
    const float lower = bottom[c] + wx * (bottom[c + 3] - bottom[c]);
    sum[c] += upper + wy * (lower - upper);
  }
}

}  // namespace

Eigen::Matrix3d SyntheticSequenceConfig::phoneImuToCamera() {
  // Columns are the IMU axes in the camera frame: x_imu = y_cam, y_imu = x_cam, z_imu = -z_cam.
  Eigen::Matrix3d R;
  R << 0, 1, 0,  //
      1, 0, 0,   //
      0, 0, -1;
  return R;
}

std::string SyntheticSequenceConfig::validate() const {
  std::ostringstream why;
  auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
  if (width_px < 16 || height_px < 16) {
    why << "width_px and height_px must be at least 16 (got " << width_px << "x" << height_px
        << ")";
  } else if (!(horizontal_fov_deg >= 1.0 && horizontal_fov_deg <= 150.0)) {
    why << "horizontal_fov_deg must be in [1, 150] (got " << horizontal_fov_deg << ")";
  } else if (plumb_bob.size() > 5 || !std::all_of(plumb_bob.begin(), plumb_bob.end(),
                                                  [](double k) { return std::isfinite(k); })) {
    why << "plumb_bob must hold at most 5 finite coefficients (k1 k2 p1 p2 k3)";
  } else if (!positive(frame_rate_hz)) {
    why << "frame_rate_hz must be positive (got " << frame_rate_hz << ")";
  } else if (!positive(duration_s) || std::floor(duration_s * frame_rate_hz) < 2.0) {
    why << "duration_s must give at least 2 frames at frame_rate_hz (got " << duration_s << " s)";
  } else if (!std::isfinite(readout_time_s) || readout_time_s < 0.0 ||
             readout_time_s >= 1.0 / frame_rate_hz) {
    why << "readout_time_s must be in [0, frame period) (got " << readout_time_s << " s)";
  } else if (supersampling < 1 || supersampling > 4) {
    why << "supersampling must be 1 to 4 (got " << supersampling << ")";
  } else if (!positive(imu_rate_hz)) {
    why << "imu_rate_hz must be positive (got " << imu_rate_hz << ")";
  } else if (!std::isfinite(imu_margin_s) || imu_margin_s < 0.0) {
    why << "imu_margin_s must be non-negative (got " << imu_margin_s << " s)";
  } else if (!std::isfinite(time_offset_s) || std::abs(time_offset_s) > 1.0) {
    why << "time_offset_s must be within +-1 s (got " << time_offset_s << " s)";
  } else if (!std::isfinite(gyro_noise_std_rad_s) || gyro_noise_std_rad_s < 0.0) {
    why << "gyro_noise_std_rad_s must be non-negative (got " << gyro_noise_std_rad_s << ")";
  } else if (!imu_to_camera_rotation.allFinite() ||
             !(imu_to_camera_rotation * imu_to_camera_rotation.transpose()).isIdentity(1e-6) ||
             std::abs(imu_to_camera_rotation.determinant() - 1.0) > 1e-6) {
    why << "imu_to_camera_rotation must be a proper rotation matrix (orthonormal, det +1)";
  } else if (sinusoids_per_axis < 0 || sinusoids_per_axis > 16) {
    why << "sinusoids_per_axis must be 0 to 16 (got " << sinusoids_per_axis << ")";
  } else if (!positive(shake_min_hz) || !std::isfinite(shake_max_hz) ||
             shake_max_hz < shake_min_hz) {
    why << "shake_min_hz must be positive and shake_max_hz at least shake_min_hz (got "
        << shake_min_hz << ", " << shake_max_hz << ")";
  } else if (!std::isfinite(shake_rate_rad_s) || shake_rate_rad_s < 0.0) {
    why << "shake_rate_rad_s must be non-negative (got " << shake_rate_rad_s << ")";
  } else if (!std::isfinite(pan_rate_rad_s)) {
    why << "pan_rate_rad_s must be finite (got " << pan_rate_rad_s << ")";
  } else if (!std::isfinite(integration_rate_hz) || integration_rate_hz < imu_rate_hz ||
             integration_rate_hz < 20.0 * shake_max_hz) {
    why << "integration_rate_hz must be at least imu_rate_hz and 20 x shake_max_hz (got "
        << integration_rate_hz << ")";
  } else if (environment_face_px < 64 || environment_face_px > 4096) {
    why << "environment_face_px must be 64 to 4096 (got " << environment_face_px << ")";
  } else if (environment_shape_count < 0 || environment_shape_count > 20000) {
    why << "environment_shape_count must be 0 to 20000 (got " << environment_shape_count << ")";
  }
  return why.str();
}

SyntheticRotationSequence::SyntheticRotationSequence(const SyntheticSequenceConfig& config)
    : config_(config) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("SyntheticSequenceConfig: " + problem);

  const double fx = 0.5 * config.width_px / std::tan(0.5 * config.horizontal_fov_deg * kPi / 180.0);
  Eigen::Matrix3d K;
  K << fx, 0, 0.5 * (config.width_px - 1), 0, fx, 0.5 * (config.height_px - 1), 0, 0, 1;
  camera_ = CameraModel(config.width_px, config.height_px, K, config.plumb_bob);
  frame_count_ = static_cast<int>(std::floor(config.duration_s * config.frame_rate_hz));

  drawMotion(config.seed);
  buildOrientationTable();
  buildImuSamples(config.seed);
  buildEnvironment(config.seed);

  // Sub-sample rays. Without distortion the normalised ray of sub-sample (i, j) is
  // (x_i, y_j, 1), so per-column and per-row tables suffice.
  const int n = config.supersampling;
  auto subPixel = [n](int pixel, int sub) { return pixel + (sub + 0.5) / n - 0.5; };
  if (!camera_.hasDistortion()) {
    sub_ray_x_.resize(static_cast<std::size_t>(config.width_px) * n);
    sub_ray_y_.resize(static_cast<std::size_t>(config.height_px) * n);
    for (int x = 0; x < config.width_px; ++x) {
      for (int i = 0; i < n; ++i) sub_ray_x_[x * n + i] = (subPixel(x, i) - K(0, 2)) / K(0, 0);
    }
    for (int y = 0; y < config.height_px; ++y) {
      for (int j = 0; j < n; ++j) sub_ray_y_[y * n + j] = (subPixel(y, j) - K(1, 2)) / K(1, 1);
    }
  } else {
    const int sub_width = config.width_px * n;
    sub_ray_xy_.resize(static_cast<std::size_t>(sub_width) * config.height_px * n);
    for (int sy = 0; sy < config.height_px * n; ++sy) {
      for (int sx = 0; sx < sub_width; ++sx) {
        const Eigen::Vector2d raw(subPixel(sx / n, sx % n), subPixel(sy / n, sy % n));
        const Eigen::Vector3d ray = camera_.Kinv() * camera_.undistort(raw).homogeneous();
        sub_ray_xy_[static_cast<std::size_t>(sy) * sub_width + sx] =
            ray.hnormalized().cast<float>();
      }
    }
  }
}

RollingShutterConfig SyntheticRotationSequence::rollingShutterConfig(int patch_count) const {
  RollingShutterConfig rs;
  rs.patch_count = patch_count;
  rs.readout_time_s = config_.readout_time_s;
  rs.time_offset_s = config_.time_offset_s;
  rs.imu_to_camera_rotation = config_.imu_to_camera_rotation;
  return rs;
}

double SyntheticRotationSequence::rowTime(int frame_index, double row_px) const {
  return frameStamp(frame_index) + config_.readout_time_s * row_px / config_.height_px;
}

ImuSampleBuffer SyntheticRotationSequence::imuBuffer() const {
  const double span = imu_samples_.back().stamp_s - imu_samples_.front().stamp_s;
  ImuSampleBuffer buffer(span + 1.0);
  for (const ImuSample& sample : imu_samples_) buffer.add(sample);
  return buffer;
}

void SyntheticRotationSequence::drawMotion(std::uint32_t seed) {
  std::mt19937 rng = streamGenerator(seed, 1);
  const double log_min = std::log(config_.shake_min_hz), log_max = std::log(config_.shake_max_hz);
  for (int axis = 0; axis < 3; ++axis) {
    const double axis_peak = config_.shake_rate_rad_s * uniform(rng, 0.6, 1.0);
    std::vector<Sinusoid>& terms = shake_[axis];
    terms.clear();
    double raw_sum = 0.0;
    for (int j = 0; j < config_.sinusoids_per_axis; ++j) {
      Sinusoid s;
      s.frequency_hz = std::exp(uniform(rng, log_min, log_max));
      // Hand shake is weaker at higher frequencies: amplitude ~ 1 / sqrt(f).
      s.amplitude_rad_s = uniform(rng, 0.5, 1.0) / std::sqrt(s.frequency_hz);
      s.phase_rad = uniform(rng, 0.0, 2.0 * kPi);
      raw_sum += s.amplitude_rad_s;
      terms.push_back(s);
    }
    for (Sinusoid& s : terms) s.amplitude_rad_s *= axis_peak / raw_sum;
  }
  // Pan: mostly yaw (camera y), a little tilt (camera x), no roll.
  const double yaw_sign = uniform01(rng) < 0.5 ? -1.0 : 1.0;
  pan_rad_s_ = Eigen::Vector3d(0.3 * config_.pan_rate_rad_s * uniform(rng, -1.0, 1.0),
                               yaw_sign * config_.pan_rate_rad_s, 0.0);
}

Eigen::Vector3d SyntheticRotationSequence::angularVelocityCamera(double t_s) const {
  Eigen::Vector3d w = pan_rad_s_;
  for (int axis = 0; axis < 3; ++axis) {
    for (const Sinusoid& s : shake_[axis]) {
      w[axis] += s.amplitude_rad_s * std::sin(2.0 * kPi * s.frequency_hz * t_s + s.phase_rad);
    }
  }
  return w;
}

namespace {

// Rotation vector of the body-frame rate w over [t, t + h]: Simpson's rule for the mean rate plus
// the coning correction; the error is far below anything a pixel can show at 4 kHz steps.
template <typename Rate>
Eigen::Vector3d stepRotationVector(const Rate& rate, double t, double h) {
  const Eigen::Vector3d w0 = rate(t), wm = rate(t + 0.5 * h), w1 = rate(t + h);
  return (h / 6.0) * (w0 + 4.0 * wm + w1) + (h * h / 12.0) * w0.cross(w1);
}

}  // namespace

void SyntheticRotationSequence::buildOrientationTable() {
  const double last_row_s = frameStamp(frame_count_ - 1) + config_.readout_time_s;
  const double slack_s = std::abs(config_.time_offset_s) + config_.imu_margin_s + 0.01;
  table_step_s_ = 1.0 / config_.integration_rate_hz;
  table_begin_s_ = -slack_s;
  const int steps = static_cast<int>(std::ceil((last_row_s + 2.0 * slack_s) / table_step_s_)) + 1;
  auto rate = [this](double t) { return angularVelocityCamera(t); };

  orientation_table_.resize(steps + 1);
  orientation_table_[0].setIdentity();
  for (int k = 0; k < steps; ++k) {
    const double t = table_begin_s_ + k * table_step_s_;
    // Body rates compose on the right: R(t + h) = R(t) exp(theta).
    orientation_table_[k + 1] =
        orientation_table_[k] * expSO3(stepRotationVector(rate, t, table_step_s_));
  }
  // Change the world frame (a constant left factor) so that R_wc(0) is the documented start:
  // optical x right, y down, z forward -> world -y, -z, x.
  Eigen::Matrix3d R_w_c0;
  R_w_c0 << 0, 0, 1,  //
      -1, 0, 0,       //
      0, -1, 0;
  const Eigen::Matrix3d fix = R_w_c0 * orientation(0.0).transpose();
  for (Eigen::Matrix3d& R : orientation_table_) R = fix * R;
}

Eigen::Matrix3d SyntheticRotationSequence::orientation(double t_s) const {
  const int last = static_cast<int>(orientation_table_.size()) - 1;
  const int k =
      std::clamp(static_cast<int>(std::floor((t_s - table_begin_s_) / table_step_s_)), 0, last - 1);
  const double t_k = table_begin_s_ + k * table_step_s_;
  const double h = t_s - t_k;
  if (h == 0.0) return orientation_table_[k];
  auto rate = [this](double t) { return angularVelocityCamera(t); };
  return orientation_table_[k] * expSO3(stepRotationVector(rate, t_k, h));
}

void SyntheticRotationSequence::buildImuSamples(std::uint32_t seed) {
  std::mt19937 rng = streamGenerator(seed, 2);
  const double last_row_s = frameStamp(frame_count_ - 1) + config_.readout_time_s;
  const double first_s = config_.time_offset_s - config_.imu_margin_s;  // IMU clock
  const double last_s = config_.time_offset_s + last_row_s + config_.imu_margin_s;
  const int count = static_cast<int>(std::ceil((last_s - first_s) * config_.imu_rate_hz)) + 1;
  const Eigen::Matrix3d R_imu_cam = config_.imu_to_camera_rotation.transpose();
  imu_samples_.clear();
  imu_samples_.reserve(count);
  for (int k = 0; k < count; ++k) {
    ImuSample sample;
    sample.stamp_s = first_s + k / config_.imu_rate_hz;
    sample.angular_velocity_rad_s =
        R_imu_cam * angularVelocityCamera(sample.stamp_s - config_.time_offset_s);
    if (config_.gyro_noise_std_rad_s > 0.0) {
      for (int axis = 0; axis < 3; ++axis) {
        sample.angular_velocity_rad_s[axis] += config_.gyro_noise_std_rad_s * gaussian(rng);
      }
    }
    imu_samples_.push_back(sample);
  }
}

void SyntheticRotationSequence::buildEnvironment(std::uint32_t seed) {
  std::mt19937 rng = streamGenerator(seed, 3);
  const std::uint32_t noise_seed = rng();

  // Shapes: sizes log-uniform from ~0.6 to ~7 degrees, painted in order (later on top).
  shapes_.clear();
  shapes_.reserve(config_.environment_shape_count);
  for (int s = 0; s < config_.environment_shape_count; ++s) {
    Shape shape;
    shape.centre = uniformUnitVector(rng);
    const Eigen::Vector3d helper =
        std::abs(shape.centre.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d e1 = shape.centre.cross(helper).normalized();
    const Eigen::Vector3d e2 = shape.centre.cross(e1);
    const double spin = uniform(rng, 0.0, kPi);
    shape.axis_u = std::cos(spin) * e1 + std::sin(spin) * e2;
    shape.axis_v = shape.centre.cross(shape.axis_u);
    const double size_rad = std::exp(uniform(rng, std::log(0.01), std::log(0.12)));
    shape.disc = uniformUnitVector(rng).x() < -0.4;  // ~30 % discs
    shape.half_u = std::tan(size_rad);
    shape.half_v = shape.disc ? shape.half_u : std::tan(size_rad * uniform(rng, 0.3, 1.0));
    shape.bound_rad = std::atan(std::hypot(shape.half_u, shape.half_v)) + 1e-3;
    shape.checkers = (!shape.disc && uniform01(rng) < 0.3) ? 2 + static_cast<int>(rng() % 4) : 0;
    shape.colour = randomColour(rng, 0.25, 1.0);
    shape.second_colour = randomColour(rng, 0.05, 0.5);
    shapes_.push_back(shape);
  }

  // The background: a few seeded palette colours blended by smooth noise, shaded by a second
  // noise and grained by a fine one.
  std::mt19937 noise_rng = streamGenerator(noise_seed, 4);
  const ValueNoise noise(noise_rng);
  cv::Vec3f palette[4];
  for (cv::Vec3f& colour : palette) colour = randomColour(rng, 0.3, 0.95);

  const int edge = config_.environment_face_px;
  const int bordered = edge + 2;
  const double half_edge = 0.5 * edge;
  // Shapes binned per tile of the face, so a texel tests only shapes that may cover it.
  const int tile_px = 32;
  const int tiles = (bordered + tile_px - 1) / tile_px;
  auto texelDirection = [&](int face, double i, double j) {
    return cubeDirection(face, (i - 0.5) / half_edge - 1.0, (j - 0.5) / half_edge - 1.0);
  };

  cube_faces_.assign(6, cv::Mat());
  for (int face = 0; face < 6; ++face) {
    std::vector<std::vector<int>> tile_shapes(static_cast<std::size_t>(tiles) * tiles);
    for (int ty = 0; ty < tiles; ++ty) {
      for (int tx = 0; tx < tiles; ++tx) {
        const double i0 = tx * tile_px - 0.5, i1 = std::min(bordered, (tx + 1) * tile_px) - 0.5;
        const double j0 = ty * tile_px - 0.5, j1 = std::min(bordered, (ty + 1) * tile_px) - 0.5;
        const Eigen::Vector3d centre =
            texelDirection(face, 0.5 * (i0 + i1), 0.5 * (j0 + j1)).normalized();
        double radius = 0.0;
        for (const Eigen::Vector3d& corner :
             {texelDirection(face, i0, j0), texelDirection(face, i1, j0),
              texelDirection(face, i0, j1), texelDirection(face, i1, j1)}) {
          radius =
              std::max(radius, std::acos(std::clamp(centre.dot(corner.normalized()), -1.0, 1.0)));
        }
        for (int s = 0; s < static_cast<int>(shapes_.size()); ++s) {
          const double reach = std::min(kPi, radius + shapes_[s].bound_rad);
          if (centre.dot(shapes_[s].centre) >= std::cos(reach)) {
            tile_shapes[ty * tiles + tx].push_back(s);
          }
        }
      }
    }

    // The background is smooth (its finest noise lattice spans ~20 texels), so it is evaluated
    // at half resolution and interpolated: a quarter of the noise evaluations.
    const int low_edge = (edge + 1) / 2;
    const double low_half_edge = 0.5 * low_edge;
    cv::Mat background(low_edge + 2, low_edge + 2, CV_32FC3);
    cv::parallel_for_(cv::Range(0, background.rows), [&](const cv::Range& rows) {
      for (int j = rows.start; j < rows.end; ++j) {
        cv::Vec3f* out = background.ptr<cv::Vec3f>(j);
        for (int i = 0; i < background.cols; ++i) {
          const Eigen::Vector3d d =
              cubeDirection(face, (i - 0.5) / low_half_edge - 1.0, (j - 0.5) / low_half_edge - 1.0)
                  .normalized();
          const float blend = noise.fractal(d, 2.5, 4);
          const float shade = noise.fractal(d + Eigen::Vector3d(31.0, 7.0, 3.0), 6.0, 3);
          const float position = smoothstep(0.3f, 0.7f, blend) * 3.0f;
          const int band = std::min(2, static_cast<int>(position));
          out[i] = mix(palette[band], palette[band + 1], smoothstep(0.2f, 0.8f, position - band)) *
                   (0.45f + 0.75f * shade);
        }
      }
    });

    cv::Mat texels(bordered, bordered, CV_8UC3);
    cv::parallel_for_(cv::Range(0, bordered), [&](const cv::Range& rows) {
      for (int j = rows.start; j < rows.end; ++j) {
        cv::Vec3b* out = texels.ptr<cv::Vec3b>(j);
        const double v = (j - 0.5) / half_edge - 1.0;
        const double fy = (v + 1.0) * low_half_edge + 0.5;  // >= 0.25
        const int y0 = static_cast<int>(fy);
        const float wy = static_cast<float>(fy - y0);
        for (int i = 0; i < bordered; ++i) {
          const double u = (i - 0.5) / half_edge - 1.0;
          const Eigen::Vector3d d = cubeDirection(face, u, v).normalized();
          const double fx = (u + 1.0) * low_half_edge + 0.5;
          const int x0 = static_cast<int>(fx);
          const float wx = static_cast<float>(fx - x0);
          const cv::Vec3f upper =
              mix(background.at<cv::Vec3f>(y0, x0), background.at<cv::Vec3f>(y0, x0 + 1), wx);
          const cv::Vec3f lower = mix(background.at<cv::Vec3f>(y0 + 1, x0),
                                      background.at<cv::Vec3f>(y0 + 1, x0 + 1), wx);
          cv::Vec3f colour = mix(upper, lower, wy);
          for (int s : tile_shapes[(j / tile_px) * tiles + i / tile_px]) {
            const Shape& shape = shapes_[s];
            const double depth = d.dot(shape.centre);
            if (depth <= 0.0) continue;
            const double a = d.dot(shape.axis_u) / depth, b = d.dot(shape.axis_v) / depth;
            bool first = true;
            if (shape.disc) {
              const double r2 = (a * a + b * b) / (shape.half_u * shape.half_u);
              if (r2 > 1.0) continue;
              first = r2 > 0.3;  // a ring around a contrasting core
            } else {
              if (std::abs(a) > shape.half_u || std::abs(b) > shape.half_v) continue;
              if (shape.checkers > 0) {
                const int ci = static_cast<int>((a / shape.half_u + 1.0) * 0.5 * shape.checkers);
                const int cj = static_cast<int>((b / shape.half_v + 1.0) * 0.5 * shape.checkers);
                first = (ci + cj) % 2 == 0;
              }
            }
            colour = first ? shape.colour : shape.second_colour;
          }
          for (int c = 0; c < 3; ++c) {
            out[i][c] =
                static_cast<std::uint8_t>(std::clamp(colour[c] * 255.0f + 0.5f, 0.0f, 255.0f));
          }
        }
      }
    });
    cube_faces_[face] = texels;
  }
}

cv::Vec3f SyntheticRotationSequence::environmentColour(
    const Eigen::Vector3d& direction_world) const {
  float sum[3] = {0.0f, 0.0f, 0.0f};
  accumulateCube(cube_faces_, 0.5 * config_.environment_face_px, direction_world.x(),
                 direction_world.y(), direction_world.z(), sum);
  return cv::Vec3f(sum[0], sum[1], sum[2]) / 255.0f;
}

void SyntheticRotationSequence::renderFrame(int frame_index, cv::Mat& rgb) const {
  if (frame_index < 0 || frame_index >= frame_count_) {
    std::ostringstream why;
    why << "SyntheticRotationSequence::renderFrame: frame " << frame_index << " outside [0, "
        << frame_count_ << ")";
    throw std::out_of_range(why.str());
  }
  const int width = config_.width_px, height = config_.height_px, n = config_.supersampling;
  rgb.create(height, width, CV_8UC3);
  const double half_edge = 0.5 * config_.environment_face_px;
  const float normaliser = 1.0f / (n * n);
  const bool distorted = camera_.hasDistortion();

  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      // The whole row is exposed at one time; its sub-samples only spread over the pixel's area.
      const Eigen::Matrix3d R = orientation(rowTime(frame_index, y));
      cv::Vec3b* out = rgb.ptr<cv::Vec3b>(y);
      for (int x = 0; x < width; ++x) {
        float sum[3] = {0.0f, 0.0f, 0.0f};
        for (int j = 0; j < n; ++j) {
          for (int i = 0; i < n; ++i) {
            double rx, ry;
            if (distorted) {
              const Eigen::Vector2f& ray =
                  sub_ray_xy_[static_cast<std::size_t>(y * n + j) * width * n + x * n + i];
              rx = ray.x(), ry = ray.y();
            } else {
              rx = sub_ray_x_[x * n + i], ry = sub_ray_y_[y * n + j];
            }
            // World ray = R * (rx, ry, 1).
            accumulateCube(cube_faces_, half_edge, R(0, 0) * rx + R(0, 1) * ry + R(0, 2),
                           R(1, 0) * rx + R(1, 1) * ry + R(1, 2),
                           R(2, 0) * rx + R(2, 1) * ry + R(2, 2), sum);
          }
        }
        for (int c = 0; c < 3; ++c) {
          out[x][c] = static_cast<std::uint8_t>(std::min(255.0f, sum[c] * normaliser + 0.5f));
        }
      }
    }
  });
}

}  // namespace deep_ois
