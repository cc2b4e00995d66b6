#include "deep_ois/core/sim/rolling_shutter_renderer.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace deep_ois {
namespace sim {

namespace {

// What a ray that hits nothing sees: a dark sky (linear RGB). The layouts avoid it.
constexpr float kMissRadiance[3] = {0.02f, 0.03f, 0.05f};
// Node spacing of the undistortion table (bilinear error ~ step^2 / 8 * |g''|: ~1e-3 px for a
// phone lens at 2 px).
constexpr double kUndistortionStepPx = 2.0;
constexpr double kGamma = 2.2;
constexpr double kPi = 3.14159265358979323846;

// The camera at one sample time of one sub-row.
struct SampleCamera {
  Eigen::Matrix3d R_cam_world;  // R_world_cam^T
  Eigen::Vector3d centre_world_m;
  double t_s, cx_px, cy_px;  // time and the lens-shifted principal point
};

// One plane for one sample camera, for the camera ray d = (xn, yn, 1) (undistorted normalised):
// s = num / (n . d) is the depth of the hit along the optical axis, and
// (u, v) = (a . d, b . d) / (n . d) are its plane coordinates as fractions of width and height.
struct PlaneCoefficients {
  float n0, n1, n2, num, a0, a1, a2, b0, b1, b2;
};

PlaneCoefficients planeCoefficients(const TexturedPlane& plane, const SampleCamera& camera) {
  const Eigen::Vector3d normal = plane.axis_u.cross(plane.axis_v);
  const Eigen::Vector3d w =
      camera.centre_world_m - (plane.origin_world_m + plane.velocity_world_m_s * camera.t_s);
  const Eigen::Vector3d n_cam = camera.R_cam_world * normal;
  const Eigen::Vector3d u_cam = camera.R_cam_world * plane.axis_u;
  const Eigen::Vector3d v_cam = camera.R_cam_world * plane.axis_v;
  const double num = -normal.dot(w);
  // u = w . axis_u + s (u_cam . d) = ((w . axis_u) (n_cam . d) + num (u_cam . d)) / (n_cam . d)
  const Eigen::Vector3d a = (w.dot(plane.axis_u) * n_cam + num * u_cam) / plane.width_m;
  const Eigen::Vector3d b = (w.dot(plane.axis_v) * n_cam + num * v_cam) / plane.height_m;
  return {static_cast<float>(n_cam.x()), static_cast<float>(n_cam.y()),
          static_cast<float>(n_cam.z()), static_cast<float>(num),
          static_cast<float>(a.x()),     static_cast<float>(a.y()),
          static_cast<float>(a.z()),     static_cast<float>(b.x()),
          static_cast<float>(b.y()),     static_cast<float>(b.z())};
}

// The samples [begin, end) of a sub-row that can hit a plane. The rays (xn[i], yn[i]) have xn
// increasing and yn within [y_lo, y_hi]; the plane's image is the convex quadrilateral of its
// projected corners, which the row crosses over one interval of xn. Only skips work: the test
// per sample stays exact. No culling when a corner is behind the camera.
void sampleRange(const TexturedPlane& plane, const SampleCamera& camera, const float* xn, int n,
                 double y_lo, double y_hi, int* begin, int* end) {
  *begin = 0;
  *end = n;
  const Eigen::Vector3d origin = plane.origin_world_m + plane.velocity_world_m_s * camera.t_s;
  const Eigen::Vector3d u = plane.width_m * plane.axis_u, v = plane.height_m * plane.axis_v;
  const Eigen::Vector3d corners[4] = {origin, origin + u, origin + u + v, origin + v};
  Eigen::Vector2d image[4];
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d X = camera.R_cam_world * (corners[k] - camera.centre_world_m);
    if (!(X.z() > 1e-6)) return;
    image[k] = X.head<2>() / X.z();
  }
  double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d& a = image[k];
    const Eigen::Vector2d& b = image[(k + 1) % 4];
    if (a.y() >= y_lo && a.y() <= y_hi) {
      x_min = std::min(x_min, a.x());
      x_max = std::max(x_max, a.x());
    }
    for (double y : {y_lo, y_hi}) {
      if ((a.y() - y) * (b.y() - y) < 0.0) {
        const double x = a.x() + (y - a.y()) / (b.y() - a.y()) * (b.x() - a.x());
        x_min = std::min(x_min, x);
        x_max = std::max(x_max, x);
      }
    }
  }
  if (!(x_min <= x_max)) {
    *end = 0;
    return;
  }
  // One sample of slack on each side for float rounding.
  *begin = std::max(0, static_cast<int>(std::lower_bound(xn, xn + n, x_min) - xn) - 1);
  *end = std::min(n, static_cast<int>(std::upper_bound(xn, xn + n, x_max) - xn) + 1);
}

// Raw access to a float RGB texture of at least 2 x 2 texels (no cv::Mat calls per sample).
struct TextureView {
  const float* data;
  std::ptrdiff_t row_step;  // floats per row
  int cols, rows;
  float last_col, last_row;
};

TextureView viewOf(const cv::Mat& texture) {
  return {texture.ptr<float>(0),
          static_cast<std::ptrdiff_t>(texture.step1()),
          texture.cols,
          texture.rows,
          static_cast<float>(texture.cols - 1),
          static_cast<float>(texture.rows - 1)};
}

// Four floats, one SIMD register wherever the compiler has one (GCC/Clang vector extension).
typedef float Float4 __attribute__((vector_size(16)));
typedef std::int32_t Int4 __attribute__((vector_size(16)));

Float4 load4(const float* p) {
  Float4 value;
  std::memcpy(&value, p, sizeof value);
  return value;
}

void store4(float* p, Float4 value) { std::memcpy(p, &value, sizeof value); }

// Lane-wise `mask ? a : b` for a comparison mask (all bits set or clear per lane).
Float4 select(Int4 mask, Float4 a, Float4 b) {
  return reinterpret_cast<Float4>((mask & reinterpret_cast<Int4>(a)) |
                                  (~mask & reinterpret_cast<Int4>(b)));
}

// plumb_bob distortion of normalised coordinates (k1, k2, p1, p2, k3) and its Jacobian, as
// CameraModel applies it.
Eigen::Vector2d distortNormalised(const Eigen::Matrix<double, 5, 1>& d, const Eigen::Vector2d& xy,
                                  Eigen::Matrix2d* jacobian) {
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  const double dradial = d[0] + r2 * (2.0 * d[1] + 3.0 * d[4] * r2);  // d radial / d r2
  *jacobian << radial + 2.0 * x * x * dradial + 2.0 * d[2] * y + 6.0 * d[3] * x,
      2.0 * x * y * dradial + 2.0 * d[2] * x + 2.0 * d[3] * y,
      2.0 * x * y * dradial + 2.0 * d[2] * x + 2.0 * d[3] * y,
      radial + 2.0 * y * y * dradial + 6.0 * d[2] * y + 2.0 * d[3] * x;
  return {x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
          y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y};
}

// Undistorted normalised coordinates as a function of the raw pixel's offset from the (shifted)
// principal point, tabulated: the lens carries its distortion centre with it, so one table
// serves every lens shift of the frame. Built per frame, so each node starts Newton from its
// neighbour's solution (two steps instead of CameraModel::undistort's cold start).
class UndistortionTable {
 public:
  UndistortionTable(const CameraModel& nominal, double qx_min, double qx_max, double qy_min,
                    double qy_max)
      : qx0_(qx_min - kUndistortionStepPx), qy0_(qy_min - kUndistortionStepPx) {
    nx_ = static_cast<int>(std::ceil((qx_max - qx0_) / kUndistortionStepPx)) + 2;
    ny_ = static_cast<int>(std::ceil((qy_max - qy0_) / kUndistortionStepPx)) + 2;
    values_.resize(2 * static_cast<std::size_t>(nx_) * ny_);
    const double fx = nominal.K()(0, 0), fy = nominal.K()(1, 1);
    if (nominal.distortionModel() != DistortionModel::kPlumbBob) {
      // Other lens models (equidistant): OpenCV's undistortion of every node in one call, on a
      // camera whose principal point is the origin of the offsets.
      Eigen::Matrix3d K_offsets = Eigen::Matrix3d::Identity();
      K_offsets(0, 0) = fx;
      K_offsets(1, 1) = fy;
      const CameraModel lens(nominal.width(), nominal.height(), K_offsets, nominal.distortionModel(),
                             nominal.coefficients());
      std::vector<Eigen::Vector2d> nodes(static_cast<std::size_t>(nx_) * ny_);
      for (int j = 0; j < ny_; ++j)
        for (int i = 0; i < nx_; ++i)
          nodes[static_cast<std::size_t>(j) * nx_ + i] =
              Eigen::Vector2d(qx0_ + i * kUndistortionStepPx, qy0_ + j * kUndistortionStepPx);
      lens.undistortPoints(nodes);
      for (std::size_t n = 0; n < nodes.size(); ++n) {
        values_[2 * n] = static_cast<float>(nodes[n].x() / fx);
        values_[2 * n + 1] = static_cast<float>(nodes[n].y() / fy);
      }
      return;
    }
    const Eigen::Matrix<double, 5, 1>& d = nominal.distortion();
    cv::parallel_for_(cv::Range(0, ny_), [&](const cv::Range& rows) {
      for (int j = rows.start; j < rows.end; ++j) {
        const double my = (qy0_ + j * kUndistortionStepPx) / fy;
        Eigen::Vector2d xy((qx0_) / fx, my);
        for (int i = 0; i < nx_; ++i) {
          const Eigen::Vector2d target((qx0_ + i * kUndistortionStepPx) / fx, my);
          for (int iteration = 0; iteration < 20; ++iteration) {
            Eigen::Matrix2d jacobian;
            const Eigen::Vector2d residual = distortNormalised(d, xy, &jacobian) - target;
            const Eigen::Vector2d step = jacobian.inverse() * residual;
            xy -= step;
            if (step.squaredNorm() < 1e-26) break;
          }
          float* node = &values_[2 * (static_cast<std::size_t>(j) * nx_ + i)];
          node[0] = static_cast<float>(xy.x());
          node[1] = static_cast<float>(xy.y());
        }
      }
    });
  }

  // The rays of a sub-row at offset qy, samples at qx = qx_first + i * dqx, i < n: the two
  // table rows around qy are blended once, then each sample interpolates along x only.
  void row(double qx_first, double dqx, double qy, int n, float* xn, float* yn,
           std::vector<float>* blended) const {
    const double gy = std::clamp((qy - qy0_) / kUndistortionStepPx, 0.0, ny_ - 1.000001);
    const int iy = static_cast<int>(gy);
    const float fy = static_cast<float>(gy - iy);
    const float* top = &values_[2 * static_cast<std::size_t>(iy) * nx_];
    const float* bottom = top + 2 * nx_;
    blended->resize(2 * static_cast<std::size_t>(nx_));
    float* line = blended->data();
    for (int k = 0; k < 2 * nx_; ++k) line[k] = top[k] + fy * (bottom[k] - top[k]);
    const double g0 = (qx_first - qx0_) / kUndistortionStepPx, dg = dqx / kUndistortionStepPx;
    for (int i = 0; i < n; ++i) {
      const double gx = std::clamp(g0 + i * dg, 0.0, nx_ - 1.000001);
      const int ix = static_cast<int>(gx);
      const float fx = static_cast<float>(gx - ix);
      xn[i] = line[2 * ix] + fx * (line[2 * ix + 2] - line[2 * ix]);
      yn[i] = line[2 * ix + 1] + fx * (line[2 * ix + 3] - line[2 * ix + 1]);
    }
  }

 private:
  double qx0_, qy0_;  // offset of node (0, 0) from the principal point, pixels
  int nx_ = 0, ny_ = 0;
  std::vector<float> values_;  // (xn, yn) per node, row-major
};

// 8-bit output code of a linear value in [0, 1] with gamma 1/2.2, exactly rounded: a coarse
// table plus the exact code thresholds (std::pow per value would cost several ms a frame).
class GammaEncoder {
 public:
  GammaEncoder() {
    threshold_[0] = -1.0f;
    for (int k = 1; k < 256; ++k) {
      threshold_[k] = static_cast<float>(std::pow((k - 0.5) / 255.0, kGamma));
    }
    int code = 0;
    for (int i = 0; i < kBins; ++i) {
      const float v = static_cast<float>(i) / kBins;
      while (code < 255 && v >= threshold_[code + 1]) ++code;
      coarse_[i] = static_cast<std::uint8_t>(code);
    }
  }

  std::uint8_t operator()(float v) const {
    v = std::clamp(v, 0.0f, 1.0f);
    int code = coarse_[std::min(kBins - 1, static_cast<int>(v * kBins))];
    while (code < 255 && v >= threshold_[code + 1]) ++code;
    return static_cast<std::uint8_t>(code);
  }

 private:
  static constexpr int kBins = 16384;
  float threshold_[256];
  std::uint8_t coarse_[kBins];
};

// Standard normal quantile, to 1e-12: Abramowitz-Stegun 26.2.23 refined by Newton steps.
double normalQuantile(double p) {
  const double q = std::min(p, 1.0 - p);
  const double t = std::sqrt(-2.0 * std::log(q));
  double z = t - (2.515517 + t * (0.802853 + t * 0.010328)) /
                     (1.0 + t * (1.432788 + t * (0.189269 + t * 0.001308)));
  if (p < 0.5) z = -z;
  for (int iteration = 0; iteration < 3; ++iteration) {
    const double cdf = 0.5 * std::erfc(-z / std::sqrt(2.0));
    const double density = std::exp(-0.5 * z * z) / std::sqrt(2.0 * kPi);
    z -= (cdf - p) / density;
  }
  return z;
}

// Gaussian draws by inverting the CDF: a quantile table with linear interpolation (error
// ~1e-6) and the exact quantile in the two outermost bins, so the tails are right. Far cheaper
// than Box-Muller's log, sqrt and sin/cos.
class NormalSampler {
 public:
  NormalSampler() {
    for (int k = 1; k < kBins; ++k) {
      quantile_[k] = static_cast<float>(normalQuantile(static_cast<double>(k) / kBins));
    }
    quantile_[0] = quantile_[1];
    quantile_[kBins] = quantile_[kBins - 1];
  }

  // A standard normal draw from 32 uniform bits.
  float operator()(std::uint32_t bits) const {
    const std::uint32_t bin = bits >> (32 - kBinBits);
    if (bin == 0 || bin == kBins - 1) {
      return static_cast<float>(normalQuantile((bits + 0.5) / 4294967296.0));
    }
    const float fraction = static_cast<float>(bits & ((1u << (32 - kBinBits)) - 1u)) *
                           (1.0f / static_cast<float>(1u << (32 - kBinBits)));
    return quantile_[bin] + fraction * (quantile_[bin + 1] - quantile_[bin]);
  }

 private:
  static constexpr int kBinBits = 12;
  static constexpr int kBins = 1 << kBinBits;
  float quantile_[kBins + 1];
};

// Counter-based noise: a hash of (seed, frame, pixel), so any frame reproduces on its own and
// the result does not depend on how rows are split among threads.
std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

RollingShutterRenderer::RollingShutterRenderer(const Scene& scene, const SimCamera& camera)
    : scene_(scene), camera_(camera) {}

cv::Mat RollingShutterRenderer::render(double stamp_s, std::uint64_t frame_index,
                                       std::uint32_t noise_seed) const {
  static const GammaEncoder encode;
  static const NormalSampler normal;
  const SensorConfig& sensor = camera_.sensor();
  const CameraModel& nominal = camera_.nominal();
  const int width = sensor.width_px, height = sensor.height_px;
  const int ss = sensor.supersampling, exposures = sensor.exposure_samples;
  // Anti-aliasing: ss * ss samples per pixel on an "n-rooks" pattern (the ss x ss grid sheared
  // so that no two samples share a row or a column): a near-vertical or near-horizontal edge
  // meets ss * ss distinct offsets instead of ss, which halves the edge placement error of a
  // regular grid. Each sample is a sub-row of its own (one sample per pixel).
  const int sub_rows = ss * ss;
  auto subRowY = [&](int j) { return (j + 0.5) / sub_rows - 0.5; };
  auto subRowX = [&](int j) { return ((j % ss) * ss + j / ss + 0.5) / sub_rows - 0.5; };
  const double fx = nominal.K()(0, 0), fy = nominal.K()(1, 1);
  const std::vector<TexturedPlane>& planes = scene_.planes();
  const int plane_count = static_cast<int>(planes.size());

  // Every sub-row at its own time (its fractional row, as the ground truth projects), and each
  // of those at `exposures` times spread evenly over the exposure (motion blur). The sub-rows of
  // a pixel take interleaved times (stratified), so a pixel integrates ss * ss * exposures
  // distinct instants: a smooth blur rather than `exposures` ghosts when the exposure is long.
  std::vector<SampleCamera> cameras(static_cast<std::size_t>(height) * sub_rows * exposures);
  double cx_min = std::numeric_limits<double>::infinity(), cx_max = -cx_min;
  double cy_min = cx_min, cy_max = -cx_min;
  for (int sub_row = 0; sub_row < height * sub_rows; ++sub_row) {
    const int j = sub_row % sub_rows;
    const double t_row = camera_.rowTime(stamp_s, sub_row / sub_rows + subRowY(j));
    const double stratum = (j + 0.5) / sub_rows;  // in (0, 1)
    for (int k = 0; k < exposures; ++k) {
      const double t = t_row + sensor.exposure_time_s * ((k + stratum) / exposures - 0.5);
      const CameraPose pose = camera_.motion().pose(t);
      const Eigen::Matrix3d K = camera_.intrinsicsAt(t);
      SampleCamera& sample = cameras[static_cast<std::size_t>(sub_row) * exposures + k];
      sample.R_cam_world = pose.R_world_cam.transpose();
      sample.centre_world_m = pose.centre_world_m;
      sample.t_s = t;
      sample.cx_px = K(0, 2);
      sample.cy_px = K(1, 2);
      cx_min = std::min(cx_min, K(0, 2));
      cx_max = std::max(cx_max, K(0, 2));
      cy_min = std::min(cy_min, K(1, 2));
      cy_max = std::max(cy_max, K(1, 2));
    }
  }
  std::unique_ptr<UndistortionTable> table;
  if (nominal.hasDistortion()) {
    table = std::make_unique<UndistortionTable>(nominal, -0.5 - cx_max, width - 0.5 - cx_min,
                                                -0.5 - cy_max, height - 0.5 - cy_min);
  }

  // Textures by 1 + plane index; 0 is the colour of a miss. Textures smaller than 2 x 2 are
  // padded (an empty one is black) so that bilinear sampling needs no bounds checks.
  std::vector<cv::Mat> padded;
  padded.reserve(plane_count + 1);
  padded.emplace_back(2, 2, CV_32FC3,
                      cv::Scalar(kMissRadiance[0], kMissRadiance[1], kMissRadiance[2]));
  std::vector<TextureView> textures{viewOf(padded.back())};
  for (const TexturedPlane& plane : planes) {
    if (plane.texture.cols >= 2 && plane.texture.rows >= 2) {
      textures.push_back(viewOf(plane.texture));
      continue;
    }
    if (plane.texture.empty()) {
      padded.emplace_back(2, 2, CV_32FC3, cv::Scalar::all(0.0));
    } else {
      padded.emplace_back();
      cv::resize(plane.texture, padded.back(),
                 cv::Size(std::max(2, plane.texture.cols), std::max(2, plane.texture.rows)), 0, 0,
                 cv::INTER_NEAREST);
    }
    textures.push_back(viewOf(padded.back()));
  }

  // Photometry: radiance * brightness is the share of the full well; shot noise is Poisson
  // (Gaussian with variance = electrons), read noise is added in electrons.
  const float weight = 1.0f / static_cast<float>(sub_rows * exposures);
  const float full_well = static_cast<float>(sensor.full_well_electrons);
  const float to_electrons = static_cast<float>(sensor.brightness * sensor.full_well_electrons);
  const float read_variance =
      static_cast<float>(sensor.read_noise_electrons * sensor.read_noise_electrons);
  const std::uint64_t frame_key = mix64(mix64(noise_seed) ^ mix64(frame_index));

  cv::Mat image(height, width, CV_8UC3);
  // Per-sample arrays are padded to whole 4-lane vectors; the padding lanes hold valid rays and
  // their results are ignored.
  const int padded_width = (width + 3) / 4 * 4;
  auto renderRows = [&](const cv::Range& rows) {
    std::vector<float> xn(padded_width), yn(padded_width), blended;
    std::vector<float> best_s(padded_width), best_u(padded_width), best_v(padded_width),
        best_plane(padded_width);  // 1 + plane index (as float), 0: missed everything
    // Radiance sums per pixel: (r, g, b, -) from left texels, (-, r, g, b) from right ones.
    std::vector<Float4> sum_left(width), sum_right(width);
    std::vector<float> radiance(3 * static_cast<std::size_t>(width));
    for (int r = rows.start; r < rows.end; ++r) {
      std::fill(sum_left.begin(), sum_left.end(), Float4{0.0f, 0.0f, 0.0f, 0.0f});
      std::fill(sum_right.begin(), sum_right.end(), Float4{0.0f, 0.0f, 0.0f, 0.0f});
      for (int j = 0; j < sub_rows; ++j) {
        const int sub_row = r * sub_rows + j;
        const double x_offset = subRowX(j), y = r + subRowY(j);
        for (int k = 0; k < exposures; ++k) {
          const SampleCamera& cam = cameras[static_cast<std::size_t>(sub_row) * exposures + k];
          // The rays of the sub-row: undistorted normalised coordinates of each sample.
          double y_lo, y_hi;
          if (table) {
            table->row(x_offset - cam.cx_px, 1.0, y - cam.cy_px, padded_width, xn.data(), yn.data(),
                       &blended);
            const auto range = std::minmax_element(yn.begin(), yn.begin() + width);
            y_lo = *range.first;
            y_hi = *range.second;
          } else {
            const double x0 = (x_offset - cam.cx_px) / fx, dx = 1.0 / fx;
            const float y_n = static_cast<float>((y - cam.cy_px) / fy);
            for (int i = 0; i < padded_width; ++i) {
              xn[i] = static_cast<float>(x0 + i * dx);
              yn[i] = y_n;
            }
            y_lo = y_hi = y_n;
          }
          // Nearest plane per ray (4 rays at a time), over the samples whose row crosses the
          // plane's image.
          std::fill(best_s.begin(), best_s.end(), std::numeric_limits<float>::infinity());
          std::fill(best_u.begin(), best_u.end(), 0.0f);
          std::fill(best_v.begin(), best_v.end(), 0.0f);
          std::fill(best_plane.begin(), best_plane.end(), 0.0f);
          for (int p = 1; p <= plane_count; ++p) {
            const TexturedPlane& plane = planes[p - 1];
            const PlaneCoefficients c = planeCoefficients(plane, cam);
            int begin, end;
            sampleRange(plane, cam, xn.data(), width, y_lo, y_hi, &begin, &end);
            for (int i = begin / 4 * 4; i < end; i += 4) {
              const Float4 x = load4(&xn[i]), yv = load4(&yn[i]);
              const Float4 inv = 1.0f / (c.n0 * x + c.n1 * yv + c.n2);
              const Float4 depth = c.num * inv;
              const Float4 u = (c.a0 * x + c.a1 * yv + c.a2) * inv;
              const Float4 v = (c.b0 * x + c.b1 * yv + c.b2) * inv;
              const Float4 nearest = load4(&best_s[i]);
              const Int4 hit = (depth > 0.0f) & (depth < nearest) & (u >= 0.0f) & (u <= 1.0f) &
                               (v >= 0.0f) & (v <= 1.0f);
              store4(&best_s[i], select(hit, depth, nearest));
              store4(&best_u[i], select(hit, u, load4(&best_u[i])));
              store4(&best_v[i], select(hit, v, load4(&best_v[i])));
              const float index = static_cast<float>(p);
              store4(&best_plane[i],
                     select(hit, Float4{index, index, index, index}, load4(&best_plane[i])));
            }
          }
          // Bilinear texture samples. The left texels load as (r, g, b, -), the right ones from
          // one float earlier as (-, r, g, b): no read past the end of a texture.
          for (int i = 0; i < width; ++i) {
            const TextureView& texture = textures[static_cast<int>(best_plane[i])];
            const float tx = best_u[i] * texture.last_col, ty = best_v[i] * texture.last_row;
            const int x0 = std::min(static_cast<int>(tx), texture.cols - 2);
            const int y0 = std::min(static_cast<int>(ty), texture.rows - 2);
            const float ax = tx - x0, ay = ty - y0;
            const float* top = texture.data + y0 * texture.row_step + 3 * x0;
            const float* bottom = top + texture.row_step;
            sum_left[i] += (1.0f - ax) * ((1.0f - ay) * load4(top) + ay * load4(bottom));
            sum_right[i] += ax * ((1.0f - ay) * load4(top + 2) + ay * load4(bottom + 2));
          }
        }
      }
      for (int i = 0; i < width; ++i) {
        radiance[3 * i] = sum_left[i][0] + sum_right[i][1];
        radiance[3 * i + 1] = sum_left[i][1] + sum_right[i][2];
        radiance[3 * i + 2] = sum_left[i][2] + sum_right[i][3];
      }
      // Sensor: electrons, noise, full-well clipping, gamma, 8 bits.
      std::uint8_t* out = image.ptr<std::uint8_t>(r);
      for (int x = 0; x < width; ++x) {
        float noise[3] = {0.0f, 0.0f, 0.0f};
        if (sensor.add_noise) {
          const std::uint64_t key = frame_key + 2 * (static_cast<std::uint64_t>(r) * width + x);
          const std::uint64_t bits0 = mix64(key), bits1 = mix64(key + 1);
          noise[0] = normal(static_cast<std::uint32_t>(bits0));
          noise[1] = normal(static_cast<std::uint32_t>(bits0 >> 32));
          noise[2] = normal(static_cast<std::uint32_t>(bits1));
        }
        for (int ch = 0; ch < 3; ++ch) {
          float electrons = radiance[3 * x + ch] * weight * to_electrons;
          electrons += noise[ch] * std::sqrt(std::max(electrons, 0.0f) + read_variance);
          out[3 * x + ch] = encode(electrons / full_well);
        }
      }
    }
  };
  cv::parallel_for_(cv::Range(0, height), renderRows, std::max(1, height / 8));
  return image;
}

}  // namespace sim
}  // namespace deep_ois
