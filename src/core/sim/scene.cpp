#include "deep_ois/core/sim/scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr const char* kDefaultTextureDir = "/usr/share/backgrounds/mate/nature";

// The view the layout must fill: 70 degrees horizontally at 4:3 (16:9 fits inside), widened
// for barrel distortion, the OIS lens shift and the anti-aliasing footprint at the border.
constexpr double kViewHalfWidthTan = 0.70020753820970977;  // tan(35 deg)
constexpr double kViewAspect = 0.75;                       // height / width
constexpr double kViewMargin = 1.2;
// Pose sampling for the coverage of the view over the motion (shake is below ~12 Hz).
constexpr double kCoverageStepS = 1.0 / 200.0;
constexpr double kCoverageExtraFraction = 0.03;  // slack added on every side of a covering plane
constexpr double kMaxPoseSamples = 20000.0;      // coarser sampling for very long motions
// MF: the moving band covers this much more than the required share of the frame (roll and
// perspective take a little), and one band follows at most this vertical drift of the view.
constexpr double kMovingCoverageMargin = 1.3;
constexpr double kMaxBandDriftTan = 0.21;  // ~12 degrees
constexpr double kBandDepthStepM = 0.1;
constexpr double kBandOverlapS = 0.25;

// Texture memory: textures are float RGB (12 bytes per texel).
constexpr int kMaxTextureSidePx = 2048;
constexpr int kMaxStripTextureColsPx = 8192;  // the moving object's long texture
constexpr double kMaxTexels = 4.0e6;

// A crop counts as textured (judged in 8-bit at its size on screen) when at least
// kTexturedMinStrong of its pixels have a gradient above kStrongGradientDn and at most
// kTexturedMaxFlat are nearly flat (below kFlatGradientDn): grass, sand, rain drops pass;
// bokeh backgrounds and smooth petals fail.
constexpr double kStrongGradientDn = 8.0;
constexpr double kFlatGradientDn = 1.0;
constexpr double kTexturedMinStrong = 0.1;
constexpr double kTexturedMaxFlat = 0.4;

// Uniform double in [0, 1) from one raw mt19937 output: the same on every standard library
// (std:: distributions are implementation-defined).
double uniform01(std::mt19937& rng) { return rng() / 4294967296.0; }
double uniform(std::mt19937& rng, double lo, double hi) { return lo + (hi - lo) * uniform01(rng); }
bool coin(std::mt19937& rng, double p_true) { return uniform01(rng) < p_true; }

// Axis-aligned box on a plane x = const of the layout frame (y left, z up), metres.
struct Box {
  double y_min = std::numeric_limits<double>::infinity();
  double y_max = -std::numeric_limits<double>::infinity();
  double z_min = std::numeric_limits<double>::infinity();
  double z_max = -std::numeric_limits<double>::infinity();
  void add(double y, double z) {
    y_min = std::min(y_min, y);
    y_max = std::max(y_max, y);
    z_min = std::min(z_min, z);
    z_max = std::max(z_max, z);
  }
  double width() const { return y_max - y_min; }
  double height() const { return z_max - z_min; }
  Box expanded(double fraction) const {
    Box box = *this;
    const double dy = fraction * width(), dz = fraction * height();
    box.y_min -= dy;
    box.y_max += dy;
    box.z_min -= dz;
    box.z_max += dz;
    return box;
  }
};

// A rectangle of directions in tangents of the layout frame: right = -y / x, down = -z / x.
struct TangentRect {
  double right_min, right_max, down_min, down_max;
  double width() const { return right_max - right_min; }
  double height() const { return down_max - down_min; }
  TangentRect intersected(const TangentRect& other) const {
    return {std::max(right_min, other.right_min), std::min(right_max, other.right_max),
            std::max(down_min, other.down_min), std::min(down_max, other.down_max)};
  }
};

// The frame a scene is laid out in, and the camera's poses in it. Origin at the camera's start
// centre; x along the middle of the range of directions the optical axis takes over the motion,
// y horizontal to the left, z up. Planes face this middle direction, so a camera panning over
// 25 degrees sees none of them more obliquely than about 12 (plus its own field of view).
class LayoutFrame {
 public:
  struct Sample {
    double t_s;
    Eigen::Matrix3d R_layout_cam;
    Eigen::Vector3d centre_m;
    double right, down;  // the optical axis, in tangents
  };

  explicit LayoutFrame(const CameraMotion& motion) {
    const double start = motion.startTime(), span = motion.endTime() - start;
    const int steps = std::max(
        1, static_cast<int>(std::ceil(span / std::max(kCoverageStepS, span / kMaxPoseSamples))));
    std::vector<CameraPose> poses;
    double yaw_min = kPi, yaw_max = -kPi, pitch_min = kPi, pitch_max = -kPi;
    for (int k = 0; k <= steps; ++k) {
      poses.push_back(motion.pose(start + span * k / steps));
      const Eigen::Vector3d axis = poses.back().R_world_cam.col(2);
      const double yaw = std::atan2(axis.y(), axis.x()),
                   pitch = std::asin(std::clamp(axis.z(), -1.0, 1.0));
      yaw_min = std::min(yaw_min, yaw);
      yaw_max = std::max(yaw_max, yaw);
      pitch_min = std::min(pitch_min, pitch);
      pitch_max = std::max(pitch_max, pitch);
    }
    const double yaw = 0.5 * (yaw_min + yaw_max), pitch = 0.5 * (pitch_min + pitch_max);
    const Eigen::Vector3d x(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw),
                            std::sin(pitch));
    const Eigen::Vector3d y(-std::sin(yaw), std::cos(yaw), 0.0);
    R_world_layout_.col(0) = x;
    R_world_layout_.col(1) = y;
    R_world_layout_.col(2) = x.cross(y);
    origin_world_m_ = poses.front().centre_world_m;
    for (int k = 0; k <= steps; ++k) {
      Sample sample;
      sample.t_s = start + span * k / steps;
      sample.R_layout_cam = R_world_layout_.transpose() * poses[k].R_world_cam;
      sample.centre_m = R_world_layout_.transpose() * (poses[k].centre_world_m - origin_world_m_);
      const Eigen::Vector3d axis = sample.R_layout_cam.col(2);
      if (!(axis.x() > 0.2)) {
        throw std::runtime_error(
            "buildScene: the camera turns by more than 78 degrees from its middle direction; the "
            "motion is too large for a planar layout");
      }
      sample.right = -axis.y() / axis.x();
      sample.down = -axis.z() / axis.x();
      samples_.push_back(sample);
    }
  }

  const std::vector<Sample>& samples() const { return samples_; }

  // The range of directions of the optical axis over the samples with t in [t_begin, t_end].
  TangentRect axisRange(double t_begin, double t_end) const {
    TangentRect range{kPi, -kPi, kPi, -kPi};
    for (const Sample& sample : samples_) {
      if (sample.t_s < t_begin || sample.t_s > t_end) continue;
      range.right_min = std::min(range.right_min, sample.right);
      range.right_max = std::max(range.right_max, sample.right);
      range.down_min = std::min(range.down_min, sample.down);
      range.down_max = std::max(range.down_max, sample.down);
    }
    return range;
  }

  // Everything the (widened) view sees of the plane x = x_m over the samples with t in
  // [t_begin, t_end]: the union of the view's corner-ray quadrilaterals (a plane cuts the view
  // pyramid in the quadrilateral of its corner rays). For a plane moving at `velocity`, the
  // quadrilaterals are taken in the plane's own frame (the point minus velocity * t), so the box
  // is what its texture must cover.
  Box viewBox(double x_m, const Eigen::Vector3d& velocity_m_s = Eigen::Vector3d::Zero(),
              double t_begin = -std::numeric_limits<double>::infinity(),
              double t_end = std::numeric_limits<double>::infinity()) const {
    const double tx = kViewHalfWidthTan * kViewMargin, ty = tx * kViewAspect;
    const Eigen::Vector3d corners[] = {
        {-tx, -ty, 1.0}, {tx, -ty, 1.0}, {tx, ty, 1.0}, {-tx, ty, 1.0}};
    Box box;
    for (const Sample& sample : samples_) {
      if (sample.t_s < t_begin || sample.t_s > t_end) continue;
      for (const Eigen::Vector3d& corner : corners) {
        const Eigen::Vector3d d = sample.R_layout_cam * corner;
        const double s = (x_m - sample.centre_m.x()) / d.x();
        if (!(d.x() > 1e-3) || !(s > 0.0)) {
          throw std::runtime_error(
              "buildScene: a view corner points away from the scene; the motion is too large "
              "for a planar layout");
        }
        const Eigen::Vector3d p = sample.centre_m + s * d - velocity_m_s * sample.t_s;
        box.add(p.y(), p.z());
      }
    }
    return box;
  }

  // A plane laid out in this frame, moved into the world.
  TexturedPlane toWorld(TexturedPlane plane) const {
    plane.origin_world_m = origin_world_m_ + R_world_layout_ * plane.origin_world_m;
    plane.axis_u = R_world_layout_ * plane.axis_u;
    plane.axis_v = R_world_layout_ * plane.axis_v;
    plane.velocity_world_m_s = R_world_layout_ * plane.velocity_world_m_s;
    return plane;
  }

 private:
  Eigen::Matrix3d R_world_layout_;
  Eigen::Vector3d origin_world_m_;
  std::vector<Sample> samples_;
};

// A rectangle facing the layout's camera, centred at `centre`, its texture upright and
// unmirrored (u = image right = -y, v = image down = -z), then rolled about the viewing axis
// and yawed about the vertical. Layout coordinates.
TexturedPlane makePlane(const Eigen::Vector3d& centre_m, double width_m, double height_m,
                        double roll_rad, double yaw_rad) {
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  TexturedPlane plane;
  plane.axis_u = R * -Eigen::Vector3d::UnitY();
  plane.axis_v = R * -Eigen::Vector3d::UnitZ();
  plane.width_m = width_m;
  plane.height_m = height_m;
  plane.origin_world_m = centre_m - 0.5 * width_m * plane.axis_u - 0.5 * height_m * plane.axis_v;
  return plane;
}

TexturedPlane planeOverBox(const Box& box, double x_m) {
  return makePlane(
      Eigen::Vector3d(x_m, 0.5 * (box.y_min + box.y_max), 0.5 * (box.z_min + box.z_max)),
      box.width(), box.height(), 0.0, 0.0);
}

// Texture resolution for a plane: a texel about half a supersample at the plane's nominal depth
// (so bilinear sampling never skips texels), never more texels than the source has, and capped.
cv::Size textureSize(double width_m, double height_m, double depth_m, double focal_px,
                     int supersampling, cv::Size source_px, int max_cols) {
  const double texel_m = depth_m / (focal_px * supersampling * 2.0);
  double cols = std::min(width_m / texel_m, static_cast<double>(source_px.width));
  cols = std::min(cols, static_cast<double>(max_cols));
  double rows = cols * height_m / width_m;
  if (rows > kMaxTextureSidePx) {
    cols *= kMaxTextureSidePx / rows;
    rows = kMaxTextureSidePx;
  }
  if (cols * rows > kMaxTexels) {
    const double shrink = std::sqrt(kMaxTexels / (cols * rows));
    cols *= shrink;
    rows *= shrink;
  }
  return cv::Size(std::max(2, static_cast<int>(std::lround(cols))),
                  std::max(2, static_cast<int>(std::lround(rows))));
}

// 8-bit sRGB-like code to linear radiance (gamma 2.2), as a lookup table.
const std::vector<float>& decodeTable() {
  static const std::vector<float> table = [] {
    std::vector<float> values(256);
    for (int i = 0; i < 256; ++i) values[i] = static_cast<float>(std::pow(i / 255.0, 2.2));
    return values;
  }();
  return table;
}

// 8-bit BGR to linear RGB float in [0, 1].
cv::Mat toLinearRgb(const cv::Mat& bgr8) {
  const std::vector<float>& decode = decodeTable();
  cv::Mat linear(bgr8.size(), CV_32FC3);
  for (int y = 0; y < bgr8.rows; ++y) {
    const std::uint8_t* in = bgr8.ptr<std::uint8_t>(y);
    float* out = linear.ptr<float>(y);
    for (int x = 0; x < bgr8.cols; ++x) {
      out[3 * x + 0] = decode[in[3 * x + 2]];
      out[3 * x + 1] = decode[in[3 * x + 1]];
      out[3 * x + 2] = decode[in[3 * x + 0]];
    }
  }
  return linear;
}

// How textured a linear texture looks to the camera: the shares of its pixels with a strong and
// with a nearly flat gradient, gamma-encoded 8-bit, at the size it appears on screen
// (`screen_cols` across).
struct TextureScore {
  double strong = 0.0, flat = 1.0;
  bool rich() const { return strong >= kTexturedMinStrong && flat <= kTexturedMaxFlat; }
  double merit() const { return strong - flat; }
};

TextureScore textureScore(const cv::Mat& linear_rgb, double screen_cols) {
  cv::Mat small;
  const double scale = std::min(1.0, screen_cols / linear_rgb.cols);
  cv::resize(linear_rgb, small, cv::Size(), scale, scale, cv::INTER_AREA);
  cv::Mat grey;
  cv::cvtColor(small, grey, cv::COLOR_RGB2GRAY);
  cv::pow(cv::max(grey, 0.0), 1.0 / 2.2, grey);
  grey *= 255.0;
  cv::Mat gx, gy, magnitude;
  cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  cv::magnitude(gx, gy, magnitude);
  const double total = static_cast<double>(magnitude.total());
  return {cv::countNonZero(magnitude > kStrongGradientDn) / total,
          cv::countNonZero(magnitude < kFlatGradientDn) / total};
}

// The photographs of a scene, in a seeded order, each read once (kept 8-bit to save memory).
class PhotoLibrary {
 public:
  PhotoLibrary(const std::vector<std::string>& paths, std::mt19937& rng) : paths_(paths) {
    for (int i = static_cast<int>(paths_.size()) - 1; i > 0; --i) {  // Fisher-Yates
      std::swap(paths_[i], paths_[static_cast<int>(uniform01(rng) * (i + 1))]);
    }
  }

  int size() const { return static_cast<int>(paths_.size()); }

  // Photo k of the seeded order (cycling), BGR 8-bit.
  const cv::Mat& photo(int k) {
    const std::string& path = paths_[k % paths_.size()];
    auto found = cache_.find(path);
    if (found != cache_.end()) return found->second;
    cv::Mat image;
    try {
      image = cv::imread(path, cv::IMREAD_COLOR);
    } catch (const cv::Exception& e) {
      throw std::runtime_error("scene texture '" + path + "' cannot be read: " + e.what());
    }
    if (image.empty() || image.cols < 16 || image.rows < 16) {
      throw std::runtime_error("scene texture '" + path +
                               "' cannot be read (missing, not an image, or smaller than 16x16)");
    }
    return cache_.emplace(path, image).first->second;
  }

 private:
  std::vector<std::string> paths_;
  std::map<std::string, cv::Mat> cache_;
};

struct CropOptions {
  double aspect = 1.0;         // width / height of the crop (= of the plane: texels stay square)
  double min_scale = 0.5;      // of the largest crop of that aspect that fits
  double max_angle_rad = 0.0;  // random rotation of the content
};

// A random rotated crop of a photograph in linear RGB, `size` texels (at most the crop's own
// resolution unless `exact_size`). The crop is taken at full resolution and reduced by area
// averaging in linear light: the pre-filter that keeps the rendered texture free of aliasing.
cv::Mat randomCrop(const cv::Mat& photo_bgr8, const CropOptions& options, cv::Size size,
                   bool exact_size, std::mt19937& rng) {
  const double angle = uniform(rng, -options.max_angle_rad, options.max_angle_rad);
  const double c = std::abs(std::cos(angle)), s = std::abs(std::sin(angle));
  const double W = photo_bgr8.cols, H = photo_bgr8.rows, a = options.aspect;
  const double h_max = std::min(W / (a * c + s), H / (a * s + c));
  const double h = h_max * uniform(rng, options.min_scale, 1.0), w = a * h;
  const double half_x = 0.5 * (w * c + h * s), half_y = 0.5 * (w * s + h * c);
  const double centre_x = uniform(rng, half_x, std::max(half_x, W - half_x)) - 0.5;
  const double centre_y = uniform(rng, half_y, std::max(half_y, H - half_y)) - 0.5;
  const bool mirror = coin(rng, 0.5);

  // Crop pixel (x, y) samples the photo at centre + Rot(angle) (x - w/2, y - h/2).
  const cv::Size crop_size(std::max(2, static_cast<int>(std::lround(w))),
                           std::max(2, static_cast<int>(std::lround(h))));
  const double ca = std::cos(angle), sa = std::sin(angle);
  const double ox = 0.5 * (crop_size.width - 1), oy = 0.5 * (crop_size.height - 1);
  const cv::Matx23d crop_to_photo(ca, -sa, centre_x - ca * ox + sa * oy,  //
                                  sa, ca, centre_y - sa * ox - ca * oy);
  cv::Mat crop;
  cv::warpAffine(photo_bgr8, crop, crop_to_photo, crop_size,
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  if (mirror) cv::flip(crop, crop, 1);
  if (!exact_size && crop.cols < size.width) size = crop.size();  // no made-up detail
  cv::Mat linear = toLinearRgb(crop);
  if (linear.size() != size) {
    const bool reducing = size.width <= linear.cols && size.height <= linear.rows;
    cv::resize(linear, linear, size, 0, 0, reducing ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  return cv::min(cv::max(linear, 0.0), 1.0);  // resampling may round a hair past [0, 1]
}

// Builds textures for the planes of one scene.
class TextureMaker {
 public:
  TextureMaker(const std::vector<std::string>& paths, std::mt19937& rng, double focal_px,
               int supersampling)
      : library_(paths, rng), rng_(rng), focal_px_(focal_px), supersampling_(supersampling) {}

  // A crop for a plane of width_m x height_m at depth_m. `textured`: try photographs (and
  // crops) in order until one is rich in texture (the best one if none is).
  cv::Mat forPlane(double width_m, double height_m, double depth_m, double max_angle_rad,
                   bool textured, int max_cols = kMaxTextureSidePx) {
    CropOptions options;
    options.aspect = width_m / height_m;
    options.max_angle_rad = max_angle_rad;
    cv::Mat best;
    double best_merit = -2.0;
    const int attempts = textured ? library_.size() : 1;
    for (int attempt = 0; attempt < attempts; ++attempt) {
      const cv::Mat& photo = library_.photo(next_++);
      const cv::Size size = textureSize(width_m, height_m, depth_m, focal_px_, supersampling_,
                                        photo.size(), max_cols);
      cv::Mat texture = randomCrop(photo, options, size, false, rng_);
      if (!textured) return texture;
      const TextureScore score = textureScore(texture, focal_px_ * width_m / depth_m);
      if (score.merit() > best_merit) {
        best_merit = score.merit();
        best = texture;
      }
      if (score.rich()) break;
    }
    return best;
  }

  // A long strip of photographs side by side (posters on a passing vehicle), height_m high.
  cv::Mat strip(double width_m, double height_m, double depth_m) {
    const cv::Size full = textureSize(width_m, height_m, depth_m, focal_px_, supersampling_,
                                      cv::Size(1 << 20, 1 << 20), kMaxStripTextureColsPx);
    const int rows = full.height;
    std::vector<cv::Mat> pieces;
    int cols = 0;
    while (cols < full.width) {
      CropOptions options;
      options.aspect = uniform(rng_, 1.0, 1.8);
      int piece_cols = static_cast<int>(std::lround(rows * options.aspect));
      if (full.width - cols - piece_cols < rows / 2) piece_cols = full.width - cols;  // no sliver
      options.aspect = static_cast<double>(piece_cols) / rows;
      options.max_angle_rad = 0.1;
      pieces.push_back(
          randomCrop(library_.photo(next_++), options, cv::Size(piece_cols, rows), true, rng_));
      cols += piece_cols;
    }
    cv::Mat texture;
    cv::hconcat(pieces, texture);
    return texture;
  }

 private:
  PhotoLibrary library_;
  std::mt19937& rng_;
  double focal_px_;
  int supersampling_;
  int next_ = 0;
};

// A sky or plain wall: a smooth vertical gradient with faint, very low-frequency variation
// (a few per cent of contrast over the whole view), linear RGB.
cv::Mat plainTexture(std::mt19937& rng, double aspect) {
  struct Palette {
    cv::Vec3f top, bottom;
  };
  const Palette palettes[] = {
      {{0.18f, 0.32f, 0.62f}, {0.45f, 0.55f, 0.70f}},  // clear sky, paler at the horizon
      {{0.50f, 0.52f, 0.56f}, {0.66f, 0.67f, 0.70f}},  // overcast
      {{0.46f, 0.40f, 0.31f}, {0.40f, 0.35f, 0.27f}},  // plain rendered wall
  };
  const Palette& palette = palettes[std::min(2, static_cast<int>(uniform01(rng) * 3))];
  const double gain = uniform(rng, 0.8, 1.1);
  const int cols = 384, rows = std::max(8, static_cast<int>(std::lround(cols / aspect)));
  struct Wave {
    double kx, ky, phase, amplitude;
  };
  std::vector<Wave> waves;
  for (int i = 0; i < 3; ++i) {
    waves.push_back({uniform(rng, 0.5, 3.0) * 2.0 * kPi / cols,
                     uniform(rng, 0.5, 3.0) * 2.0 * kPi / rows, uniform(rng, 0.0, 2.0 * kPi),
                     uniform(rng, 0.004, 0.012)});
  }
  cv::Mat texture(rows, cols, CV_32FC3);
  for (int y = 0; y < rows; ++y) {
    const float blend = static_cast<float>(y) / (rows - 1);
    for (int x = 0; x < cols; ++x) {
      double variation = 1.0;
      for (const Wave& wave : waves) {
        variation += wave.amplitude * std::sin(wave.kx * x + wave.ky * y + wave.phase);
      }
      const cv::Vec3f colour = (1.0f - blend) * palette.top + blend * palette.bottom;
      texture.at<cv::Vec3f>(y, x) = colour * static_cast<float>(gain * variation);
    }
  }
  return cv::min(texture, 1.0f);
}

// The nominal (unwidened) view around an optical axis direction, in tangents.
TangentRect viewAround(double right, double down) {
  const double half_w = kViewHalfWidthTan, half_h = kViewHalfWidthTan * kViewAspect;
  return {right - half_w, right + half_w, down - half_h, down + half_h};
}

// Near layers: photographs on boards between the camera and the background, one per depth bin
// over [depth_min, depth_max] (bins keep tilted boards from crossing). Board i sits in the view
// of a time stratified over the motion (so a long pan keeps meeting boards), inside `region`,
// rolled and yawed a little: not all fronto-parallel. Layout coordinates.
void addNearBoards(int count, double depth_min_m, double depth_max_m, const TangentRect& region,
                   const LayoutFrame& frame, TextureMaker& textures, std::mt19937& rng,
                   std::vector<TexturedPlane>* planes) {
  if (count <= 0 || !(depth_max_m > depth_min_m)) return;
  const std::vector<LayoutFrame::Sample>& samples = frame.samples();
  const double bin_m = (depth_max_m - depth_min_m) / count;
  const double half_w = kViewHalfWidthTan, half_h = kViewHalfWidthTan * kViewAspect;
  for (int i = 0; i < count; ++i) {
    const double depth = depth_min_m + bin_m * (i + uniform(rng, 0.3, 0.7));
    const double when = (i + uniform(rng, 0.2, 0.8)) / count;
    const LayoutFrame::Sample& sample =
        samples[std::min(samples.size() - 1, static_cast<std::size_t>(when * samples.size()))];
    // Inside the central 80 % of that view and inside the region.
    TangentRect allowed = viewAround(sample.right, sample.down);
    allowed = {allowed.right_min + 0.1 * half_w, allowed.right_max - 0.1 * half_w,
               allowed.down_min + 0.1 * half_h, allowed.down_max - 0.1 * half_h};
    allowed = allowed.intersected(region);
    const double roll = uniform(rng, -0.25, 0.25);
    double width_tan = 2.0 * half_w * uniform(rng, 0.22, 0.45);
    double height_tan = width_tan / uniform(rng, 0.7, 1.5);
    if (allowed.width() < 0.2 * half_w || allowed.height() < 0.2 * half_h) continue;
    // Shrunk until the rolled board's bounding box fits.
    const double c = std::cos(roll), s = std::abs(std::sin(roll));
    const double fit = std::min({1.0, 0.95 * allowed.width() / (width_tan * c + height_tan * s),
                                 0.95 * allowed.height() / (width_tan * s + height_tan * c)});
    width_tan *= fit;
    height_tan *= fit;
    const double box_x = 0.5 * (width_tan * c + height_tan * s);
    const double box_y = 0.5 * (width_tan * s + height_tan * c);
    const double right = uniform(rng, allowed.right_min + box_x, allowed.right_max - box_x);
    const double down = uniform(rng, allowed.down_min + box_y, allowed.down_max - box_y);
    const double width_m = width_tan * depth, height_m = height_tan * depth;
    // Yaw limited so the board's depth span stays inside its bin.
    const double max_sin_yaw = std::min(0.4, 0.4 * bin_m / (0.5 * (width_m + height_m)));
    const double yaw = std::asin(uniform(rng, -max_sin_yaw, max_sin_yaw));
    TexturedPlane plane =
        makePlane(depth * Eigen::Vector3d(1.0, -right, -down), width_m, height_m, roll, yaw);
    plane.texture = textures.forPlane(width_m, height_m, depth, 0.15, false);
    planes->push_back(std::move(plane));
  }
}

// The plane covering everything the view sees at depth_m over the whole motion, textured with a
// rich photograph.
TexturedPlane background(double depth_m, const LayoutFrame& frame, TextureMaker& textures) {
  TexturedPlane plane =
      planeOverBox(frame.viewBox(depth_m).expanded(kCoverageExtraFraction), depth_m);
  plane.texture = textures.forPlane(plane.width_m, plane.height_m, depth_m, 0.15, true);
  return plane;
}

// LT: a plain sky or wall fills the view; a textured band (a photo of a meadow, dune, leaves...)
// covers the rest at the bottom or on one side, with the near boards inside it. The boundary is
// put across the axis the camera drifts least along, so the plain share stays near its target.
void lowTextureLayout(const SceneConfig& config, const LayoutFrame& frame, TextureMaker& textures,
                      std::mt19937& rng, std::vector<TexturedPlane>* planes) {
  const double fraction = config.low_texture_fraction;
  const bool sky = coin(rng, 0.67);
  const double plain_depth =
      sky ? config.background_depth_max_m
          : uniform(rng, config.background_depth_min_m,
                    0.5 * (config.background_depth_min_m + config.background_depth_max_m));
  TexturedPlane plain =
      planeOverBox(frame.viewBox(plain_depth).expanded(kCoverageExtraFraction), plain_depth);
  plain.texture = plainTexture(rng, plain.width_m / plain.height_m);
  planes->push_back(std::move(plain));

  const double band_depth =
      std::max(config.near_depth_max_m + 0.5, plain_depth * uniform(rng, 0.5, 0.8));
  Box band = frame.viewBox(band_depth).expanded(kCoverageExtraFraction);
  const TangentRect drift = frame.axisRange(-std::numeric_limits<double>::infinity(),
                                            std::numeric_limits<double>::infinity());
  const TangentRect view = viewAround(0.5 * (drift.right_min + drift.right_max),
                                      0.5 * (drift.down_min + drift.down_max));
  constexpr double kFar = 1e3;  // tangent: unbounded
  TangentRect textured{-kFar, kFar, -kFar, kFar};
  if (drift.height() <= drift.width()) {  // textured at the bottom
    textured.down_min = view.down_min + fraction * view.height();
    band.z_max = -textured.down_min * band_depth;
  } else if (coin(rng, 0.5)) {  // on the left
    textured.right_max = view.right_max - fraction * view.width();
    band.y_min = -textured.right_max * band_depth;
  } else {  // on the right
    textured.right_min = view.right_min + fraction * view.width();
    band.y_max = -textured.right_min * band_depth;
  }
  TexturedPlane strip = planeOverBox(band, band_depth);
  strip.texture = textures.forPlane(strip.width_m, strip.height_m, band_depth, 0.05, true);
  planes->push_back(std::move(strip));
  addNearBoards(config.near_layer_count, config.near_depth_min_m, config.near_depth_max_m, textured,
                frame, textures, rng, planes);
}

// MF: bands of posters (passing vehicles) at moving_object_depth_m, moving sideways, each as wide
// as the view over its stretch of time plus the distance it travels. A band spans the view's
// vertical drift over its stretch plus the required share of the frame, so it covers that share
// at every instant without hiding the static scene; a camera that drifts far up or down gets one
// band per stretch (slightly deeper each, so that none coincide). Near boards only behind them,
// so nothing hides them. Returns the depth of the deepest band.
double movingObjectLayout(const SceneConfig& config, const LayoutFrame& frame,
                          TextureMaker& textures, std::mt19937& rng,
                          std::vector<TexturedPlane>* planes) {
  const double half_band =
      kViewHalfWidthTan * kViewAspect * config.moving_object_min_coverage * kMovingCoverageMargin;
  const Eigen::Vector3d velocity(
      0.0, (coin(rng, 0.5) ? 1.0 : -1.0) * config.moving_object_speed_m_s, 0.0);
  const std::vector<LayoutFrame::Sample>& samples = frame.samples();
  double depth = config.moving_object_depth_m;
  std::size_t first = 0;
  for (int band_index = 0; first < samples.size(); ++band_index) {
    // The longest stretch from `first` whose vertical drift stays within the limit.
    double down_min = samples[first].down, down_max = down_min;
    std::size_t last = first;
    while (last + 1 < samples.size()) {
      const double down = samples[last + 1].down;
      if (std::max(down_max, down) - std::min(down_min, down) > kMaxBandDriftTan) break;
      down_min = std::min(down_min, down);
      down_max = std::max(down_max, down);
      ++last;
    }
    depth = config.moving_object_depth_m + kBandDepthStepM * band_index;
    // Overlapping stretches: no gap where one band hands over to the next.
    Box band = frame
                   .viewBox(depth, velocity, samples[first].t_s - kBandOverlapS,
                            samples[last].t_s + kBandOverlapS)
                   .expanded(kCoverageExtraFraction);
    band.z_min = -(down_max + half_band) * depth;
    band.z_max = -(down_min - half_band) * depth;
    TexturedPlane object = planeOverBox(band, depth);
    object.texture = textures.strip(object.width_m, object.height_m, depth);
    object.velocity_world_m_s = velocity;
    planes->push_back(std::move(object));
    first = last + 1;
  }
  return depth;
}

}  // namespace

const char* toString(Category category) {
  switch (category) {
    case Category::kRegular:
      return "RE";
    case Category::kLowTexture:
      return "LT";
    case Category::kLowLight:
      return "LL";
    case Category::kMovingForeground:
      return "MF";
  }
  return "?";
}

bool parseCategory(const std::string& text, Category* category) {
  for (Category candidate : {Category::kRegular, Category::kLowTexture, Category::kLowLight,
                             Category::kMovingForeground}) {
    if (text == toString(candidate)) {
      *category = candidate;
      return true;
    }
  }
  return false;
}

std::string SceneConfig::validate() const {
  std::ostringstream why;
  for (const std::string& path : texture_paths) {
    if (path.empty()) return "texture_paths must not contain empty entries";
  }
  if (near_layer_count < 0 || near_layer_count > 16) {
    why << "near_layer_count must be between 0 and 16 (got " << near_layer_count << ")";
  } else if (!(near_depth_min_m > 0.1 && near_depth_max_m > near_depth_min_m)) {
    why << "near_depth_min_m/near_depth_max_m need 0.1 < min < max (got " << near_depth_min_m
        << ", " << near_depth_max_m << ")";
  } else if (!(background_depth_min_m > near_depth_max_m &&
               background_depth_max_m >= background_depth_min_m &&
               background_depth_max_m <= 1.0e4)) {
    why << "background_depth_min_m/background_depth_max_m need near_depth_max_m < min <= max "
           "<= 10000 (got "
        << background_depth_min_m << ", " << background_depth_max_m << ")";
  } else if (!(low_texture_fraction >= 0.0 && low_texture_fraction <= 0.9)) {
    why << "low_texture_fraction must be in [0, 0.9] (got " << low_texture_fraction << ")";
  } else if (!(moving_object_depth_m > 0.1 && moving_object_depth_m < background_depth_min_m)) {
    why << "moving_object_depth_m must be in (0.1, background_depth_min_m) (got "
        << moving_object_depth_m << ")";
  } else if (!(moving_object_speed_m_s >= 0.0 && moving_object_speed_m_s <= 50.0)) {
    why << "moving_object_speed_m_s must be in [0, 50] (got " << moving_object_speed_m_s << ")";
  } else if (!(moving_object_min_coverage >= 0.2 && moving_object_min_coverage <= 0.7)) {
    why << "moving_object_min_coverage must be in [0.2, 0.7] (got " << moving_object_min_coverage
        << ")";
  }
  return why.str();
}

std::vector<std::string> defaultTexturePaths() {
  std::vector<std::string> paths;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(kDefaultTextureDir, error)) {
    if (!entry.is_regular_file(error)) continue;
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    if (extension == ".jpg" || extension == ".jpeg" || extension == ".png") {
      paths.push_back(entry.path().string());
    }
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

Scene::Scene(std::vector<TexturedPlane> planes) : planes_(std::move(planes)) {
  for (std::size_t i = 0; i < planes_.size(); ++i) {
    const TexturedPlane& plane = planes_[i];
    std::ostringstream why;
    if (!(plane.width_m > 0.0 && plane.height_m > 0.0)) {
      why << "plane " << i << ": width_m and height_m must be positive";
    } else if (std::abs(plane.axis_u.norm() - 1.0) > 1e-9 ||
               std::abs(plane.axis_v.norm() - 1.0) > 1e-9 ||
               std::abs(plane.axis_u.dot(plane.axis_v)) > 1e-9) {
      why << "plane " << i << ": axis_u and axis_v must be orthonormal";
    } else if (!plane.texture.empty() && plane.texture.type() != CV_32FC3) {
      why << "plane " << i << ": texture must be CV_32FC3 (linear RGB)";
    } else if (!plane.origin_world_m.allFinite() || !plane.velocity_world_m_s.allFinite()) {
      why << "plane " << i << ": origin and velocity must be finite";
    }
    if (!why.str().empty()) throw std::invalid_argument("Scene: " + why.str());
  }
}

namespace {

// Bilinear sample of plane coordinates (u, v) in metres; texel (0, 0) sits at (0, 0) and the
// last texel at (width, height).
Eigen::Vector3f sampleTexture(const TexturedPlane& plane, double u_m, double v_m) {
  const cv::Mat& texture = plane.texture;
  if (texture.empty()) return Eigen::Vector3f::Zero();
  const double x = std::clamp(u_m * (texture.cols - 1) / plane.width_m, 0.0, texture.cols - 1.0);
  const double y = std::clamp(v_m * (texture.rows - 1) / plane.height_m, 0.0, texture.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, texture.cols - 1), y1 = std::min(y0 + 1, texture.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const cv::Vec3f top =
      (1.0f - fx) * texture.at<cv::Vec3f>(y0, x0) + fx * texture.at<cv::Vec3f>(y0, x1);
  const cv::Vec3f bottom =
      (1.0f - fx) * texture.at<cv::Vec3f>(y1, x0) + fx * texture.at<cv::Vec3f>(y1, x1);
  const cv::Vec3f value = (1.0f - fy) * top + fy * bottom;
  return Eigen::Vector3f(value[0], value[1], value[2]);
}

}  // namespace

bool Scene::intersect(const Eigen::Vector3d& origin_world_m, const Eigen::Vector3d& direction,
                      double t_s, SceneHit* hit) const {
  double best_s = std::numeric_limits<double>::infinity();
  int best = -1;
  double best_u = 0.0, best_v = 0.0;
  for (std::size_t i = 0; i < planes_.size(); ++i) {
    const TexturedPlane& plane = planes_[i];
    const Eigen::Vector3d normal = plane.axis_u.cross(plane.axis_v);
    const double approach = normal.dot(direction);
    if (std::abs(approach) < 1e-12) continue;  // parallel: a plane seen edge-on is invisible
    const Eigen::Vector3d origin_t = plane.origin_world_m + plane.velocity_world_m_s * t_s;
    const double s = normal.dot(origin_t - origin_world_m) / approach;
    if (!(s > 0.0) || s >= best_s) continue;
    const Eigen::Vector3d local = origin_world_m + s * direction - origin_t;
    const double u = local.dot(plane.axis_u), v = local.dot(plane.axis_v);
    if (u < 0.0 || u > plane.width_m || v < 0.0 || v > plane.height_m) continue;
    best_s = s;
    best = static_cast<int>(i);
    best_u = u;
    best_v = v;
  }
  if (best < 0) return false;
  if (hit != nullptr) {
    const TexturedPlane& plane = planes_[best];
    hit->distance_m = best_s;
    hit->plane_index = best;
    hit->is_static = plane.isStatic();
    hit->point_world_m = origin_world_m + best_s * direction;
    hit->radiance = sampleTexture(plane, best_u, best_v);
  }
  return true;
}

Scene buildScene(const SceneConfig& config, Category category, std::uint32_t seed,
                 const CameraMotion& motion, double focal_px, int supersampling) {
  const std::string problem = config.validate();
  if (!problem.empty()) throw std::invalid_argument("buildScene: scene config: " + problem);
  if (!(focal_px > 0.0) || supersampling < 1) {
    throw std::invalid_argument("buildScene: focal_px and supersampling must be positive");
  }
  const std::vector<std::string> paths =
      config.texture_paths.empty() ? defaultTexturePaths() : config.texture_paths;
  if (paths.empty()) {
    throw std::runtime_error(std::string("buildScene: no texture photographs: scene.texture_paths "
                                         "is empty and ") +
                             kDefaultTextureDir +
                             " holds none (install mate-backgrounds: scripts/install_deps.sh)");
  }

  std::mt19937 rng(seed ^ 0x5CE7E5EEu);
  TextureMaker textures(paths, rng, focal_px, supersampling);
  const LayoutFrame frame(motion);
  constexpr double kFar = 1e3;  // tangent: unbounded
  const TangentRect anywhere{-kFar, kFar, -kFar, kFar};
  std::vector<TexturedPlane> planes;
  switch (category) {
    case Category::kLowTexture:
      lowTextureLayout(config, frame, textures, rng, &planes);
      break;
    case Category::kRegular:
    case Category::kLowLight:  // the RE layout: darkness is the sensor's
      planes.push_back(
          background(uniform(rng, config.background_depth_min_m, config.background_depth_max_m),
                     frame, textures));
      addNearBoards(config.near_layer_count, config.near_depth_min_m, config.near_depth_max_m,
                    anywhere, frame, textures, rng, &planes);
      break;
    case Category::kMovingForeground: {
      planes.push_back(
          background(uniform(rng, config.background_depth_min_m, config.background_depth_max_m),
                     frame, textures));
      const double deepest = movingObjectLayout(config, frame, textures, rng, &planes);
      addNearBoards(config.near_layer_count, std::max(config.near_depth_min_m, deepest + 0.5),
                    config.near_depth_max_m, anywhere, frame, textures, rng, &planes);
      break;
    }
  }
  for (TexturedPlane& plane : planes) plane = frame.toWorld(std::move(plane));
  return Scene(std::move(planes));
}

}  // namespace sim
}  // namespace deep_ois
