#include "deep_ois/core/flow/backward_map.h"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/flow/working_grid.h"

namespace deep_ois {
namespace {

// cv::remap's fixed-point resolution: 1/32 pixel (INTER_BITS = 5).
constexpr int kFractionBits = 5;
constexpr int kFractionSteps = 1 << kFractionBits;
// Positions are clamped here before the fixed-point conversion so that no int overflows: anything
// this far out is outside every image remap can take (short coordinates) and reads as black.
constexpr float kFarOutsidePx = 30000.0f;

void checkInputs(const cv::Mat& flow_grid, cv::Size image_size, int iterations, const char* caller) {
  if (flow_grid.empty() || flow_grid.type() != CV_32FC2) {
    throw std::invalid_argument(std::string(caller) + ": the flow must be a non-empty CV_32FC2 image");
  }
  if (image_size.width <= 0 || image_size.height <= 0) {
    throw std::invalid_argument(std::string(caller) + ": the camera size must be positive");
  }
  if (iterations < 0) throw std::invalid_argument(std::string(caller) + ": iterations must be >= 0");
}

// A camera no larger than the grid has fewer pixels than the grid has nodes: the motion lives at
// camera resolution, where inverseFlowMap inverts every pixel.
bool cameraWithinGrid(const cv::Mat& flow_grid, cv::Size image_size) {
  return image_size.width <= flow_grid.cols && image_size.height <= flow_grid.rows;
}

// The forward flow in camera pixels at any camera position: bilinear between the grid nodes
// (camera pixel (g + 0.5) s - 0.5), the border nodes' values continued outwards, as
// gridFlowToCameraFlow and inverseFlowMap's border replication see it.
class GridFlowSampler {
 public:
  GridFlowSampler(const cv::Mat& flow_grid, cv::Size image_size) {
    const WorkingGrid grid(image_size, flow_grid.size());
    sx_ = static_cast<float>(grid.scale().x());
    sy_ = static_cast<float>(grid.scale().y());
    cv::multiply(flow_grid, cv::Scalar(sx_, sy_), flow_px_);
    inv_sx_ = 1.0f / sx_;
    inv_sy_ = 1.0f / sy_;
    max_gx_ = flow_px_.cols - 1.0f;
    max_gy_ = flow_px_.rows - 1.0f;
  }

  const cv::Mat& flowPx() const { return flow_px_; }  // CV_32FC2 on the grid, camera pixels
  float scaleX() const { return sx_; }
  float scaleY() const { return sy_; }

  void sample(float px, float py, float& u, float& v) const {
    const float gx = std::clamp((px + 0.5f) * inv_sx_ - 0.5f, 0.0f, max_gx_);
    const float gy = std::clamp((py + 0.5f) * inv_sy_ - 0.5f, 0.0f, max_gy_);
    const int x0 = std::min(static_cast<int>(gx), flow_px_.cols - 1), y0 = std::min(static_cast<int>(gy), flow_px_.rows - 1);
    const int x1 = std::min(x0 + 1, flow_px_.cols - 1), y1 = std::min(y0 + 1, flow_px_.rows - 1);
    const float fx = gx - x0, fy = gy - y0;
    const cv::Vec2f* top = flow_px_.ptr<cv::Vec2f>(y0);
    const cv::Vec2f* bottom = flow_px_.ptr<cv::Vec2f>(y1);
    const float top_u = top[x0][0] + fx * (top[x1][0] - top[x0][0]);
    const float top_v = top[x0][1] + fx * (top[x1][1] - top[x0][1]);
    const float bottom_u = bottom[x0][0] + fx * (bottom[x1][0] - bottom[x0][0]);
    const float bottom_v = bottom[x0][1] + fx * (bottom[x1][1] - bottom[x0][1]);
    u = top_u + fy * (bottom_u - top_u);
    v = top_v + fy * (bottom_v - top_v);
  }

 private:
  cv::Mat flow_px_;
  float sx_ = 1.0f, sy_ = 1.0f, inv_sx_ = 1.0f, inv_sy_ = 1.0f, max_gx_ = 0.0f, max_gy_ = 0.0f;
};

// The forward flow exactly as inverseFlowMap samples it, for the pixels computed one by one: the
// grid resized to camera pixels (cv::resize, bilinear, border clamped), then read bilinearly by
// cv::remap at positions rounded to 1/32 pixel, the border replicated. Near a kink of the flow this
// differs from sampling the grid directly by up to about 0.01 px, which the accuracy bound cannot
// spare. Each camera-pixel value is computed on demand (only a few pixels need it).
class ReferenceFlowSampler {
 public:
  ReferenceFlowSampler(const cv::Mat& flow_grid, cv::Size image_size)
      : flow_grid_(flow_grid), width_(image_size.width), height_(image_size.height) {
    const WorkingGrid grid(image_size, flow_grid.size());
    sx_ = static_cast<float>(grid.scale().x());
    sy_ = static_cast<float>(grid.scale().y());
    axis(image_size.width, flow_grid.cols, column_lower_, column_weight_);
    axis(image_size.height, flow_grid.rows, row_lower_, row_weight_);
  }

  // One step of inverseFlowMap's iteration at camera pixel (qx, qy): p <- q - flow(p).
  void stepAt(int qx, int qy, float& px, float& py) const {
    float u, v;
    sample(px, py, u, v);
    px = static_cast<float>(qx) - u;
    py = static_cast<float>(qy) - v;
  }

  // inverseFlowMap's iteration at camera pixel (qx, qy): p = q - flow(q), p <- q - flow(p).
  void invertAt(int qx, int qy, int iterations, float& px, float& py) const {
    float u, v;
    cameraFlow(qx, qy, u, v);
    for (int i = 0; i < iterations; ++i) {
      px = static_cast<float>(qx) - u;
      py = static_cast<float>(qy) - v;
      sample(px, py, u, v);
    }
    px = static_cast<float>(qx) - u;
    py = static_cast<float>(qy) - v;
  }

 private:
  // cv::resize's bilinear source position per destination pixel, clamped at the border.
  static void axis(int camera_pixels, int grid_pixels, std::vector<int>& lower, std::vector<float>& weight) {
    lower.resize(camera_pixels);
    weight.resize(camera_pixels);
    const double grid_per_camera = static_cast<double>(grid_pixels) / camera_pixels;
    for (int i = 0; i < camera_pixels; ++i) {
      float g = static_cast<float>((i + 0.5) * grid_per_camera - 0.5);
      int g0 = cvFloor(g);
      g -= static_cast<float>(g0);
      if (g0 < 0) g = 0.0f, g0 = 0;
      if (g0 >= grid_pixels - 1) g = 0.0f, g0 = grid_pixels - 1;
      lower[i] = g0;
      weight[i] = g;
    }
  }

  // The resized flow at camera pixel (x, y), in camera pixels.
  void cameraFlow(int x, int y, float& u, float& v) const {
    gridFlow(column_lower_[x], row_lower_[y], column_weight_[x], row_weight_[y], u, v);
  }

  // The grid flow between nodes (x0, y0) and the next ones at weights a, b, in camera pixels.
  void gridFlow(int x0, int y0, float a, float b, float& u, float& v) const {
    const int x1 = std::min(x0 + 1, flow_grid_.cols - 1), y1 = std::min(y0 + 1, flow_grid_.rows - 1);
    const cv::Vec2f* top = flow_grid_.ptr<cv::Vec2f>(y0);
    const cv::Vec2f* bottom = flow_grid_.ptr<cv::Vec2f>(y1);
    const float top_u = top[x0][0] * (1.0f - a) + top[x1][0] * a, top_v = top[x0][1] * (1.0f - a) + top[x1][1] * a;
    const float bottom_u = bottom[x0][0] * (1.0f - a) + bottom[x1][0] * a;
    const float bottom_v = bottom[x0][1] * (1.0f - a) + bottom[x1][1] * a;
    u = (top_u * (1.0f - b) + bottom_u * b) * sx_;
    v = (top_v * (1.0f - b) + bottom_v * b) * sy_;
  }

  void sample(float px, float py, float& u, float& v) const {
    const int ix = cvRound(std::clamp(px, -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
    const int iy = cvRound(std::clamp(py, -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
    const int x = ix >> kFractionBits, y = iy >> kFractionBits;
    const float ax = static_cast<float>(ix & (kFractionSteps - 1)) / kFractionSteps;
    const float ay = static_cast<float>(iy & (kFractionSteps - 1)) / kFractionSteps;
    const int x0 = std::clamp(x, 0, width_ - 1), x1 = std::clamp(x + 1, 0, width_ - 1);
    const int y0 = std::clamp(y, 0, height_ - 1), y1 = std::clamp(y + 1, 0, height_ - 1);
    float u00, v00, u01, v01, u10, v10, u11, v11;
    cameraFlow(x0, y0, u00, v00);
    cameraFlow(x1, y0, u01, v01);
    cameraFlow(x0, y1, u10, v10);
    cameraFlow(x1, y1, u11, v11);
    const float w00 = (1.0f - ay) * (1.0f - ax), w01 = (1.0f - ay) * ax, w10 = ay * (1.0f - ax), w11 = ay * ax;
    u = u00 * w00 + u01 * w01 + u10 * w10 + u11 * w11;
    v = v00 * w00 + v01 * w01 + v10 * w10 + v11 * w11;
  }

  cv::Mat flow_grid_;  // a header sharing the caller's flow
  int width_, height_;
  float sx_ = 1.0f, sy_ = 1.0f;
  std::vector<int> column_lower_, row_lower_;
  std::vector<float> column_weight_, row_weight_;
};

// Interpolation between grid nodes along one axis: camera pixel i reads grid position
// (i + 0.5) / s - 0.5 = node `lower` + `weight` towards node `lower + 1`, continued linearly past the
// outermost nodes (the smooth inverse goes on there; holding it constant would cost up to a
// gradient times half a grid cell). `first_pixel[c]` is the first camera pixel of cell c (between
// nodes c and c + 1; the outer half cells belong to the first and last cells).
struct AxisInterpolation {
  std::vector<int> lower;
  std::vector<float> weight;
  std::vector<int> first_pixel;

  AxisInterpolation(int camera_pixels, int grid_pixels) : lower(camera_pixels), weight(camera_pixels) {
    const int cells = std::max(1, grid_pixels - 1);
    first_pixel.assign(cells + 1, camera_pixels);
    const double grid_per_camera = static_cast<double>(grid_pixels) / camera_pixels;
    for (int i = camera_pixels - 1; i >= 0; --i) {
      const double g = (i + 0.5) * grid_per_camera - 0.5;
      lower[i] = grid_pixels < 2 ? 0 : std::clamp(static_cast<int>(std::floor(g)), 0, grid_pixels - 2);
      weight[i] = grid_pixels < 2 ? 0.0f : static_cast<float>(g - lower[i]);
      first_pixel[lower[i]] = i;
    }
    for (int c = cells - 1; c >= 0; --c) first_pixel[c] = std::min(first_pixel[c], first_pixel[c + 1]);
  }
};

}  // namespace

// The working buffers of a map build at grid resolution, kept from frame to frame (FixedPointMap
// holds one): fresh buffers of a few MB per frame would each be an mmap and its page faults.
struct BackwardMapScratch {
  cv::Mat position, flow_at_position;  // CV_32FC2 on the grid: the iteration's positions and reads
  cv::Mat displacement;                // CV_32FC2 on the grid: p - q in camera pixels
  cv::Mat horizontal;                  // CV_32FC2, grid rows x camera columns: d interpolated along x
  cv::Mat kink_across_x, kink_across_y;  // CV_8U per node: 0 none, 1 kink, 2 strong kink
  cv::Mat cell_work;                     // CV_8U per cell of frame b: GridInverse::CellWork
};

namespace {

// Everything the map of one pair needs at grid resolution: the inverse at the nodes, and which grid
// cells of frame b hold a kink of the inverse that bilinear interpolation between nodes would
// smooth over (there the map is computed per camera pixel, as inverseFlowMap does).
//
// A kink of the inverse sits where the backward position p crosses a kink of the forward flow. The
// forward flow is bilinear between grid nodes, so it kinks on node lines, by its second difference
// there (a patch seam of the gyro flow, the coarse lattice the network's output is resized from,
// and the border, past which the flow is held constant); interpolating across a kink of second
// difference k errs by up to about k / 4. The cells of frame b that the image of such a node-line
// segment (kink above kKinkPx at either end) passes through, with a margin, are finished per
// camera pixel:
// - one fixed-point step p <- q - flow(p) from the interpolated p, which is within k / 4 of the
//   answer, so the step lands within (flow gradient) x k / 4 of it; within a pixel and a half of
//   the border node lines, where inverseFlowMap's camera-resolution sampling differs from the
//   grid's by up to a quarter of the flow gradient, with inverseFlowMap's own sampling;
// - near a strong kink (above kStrongKinkPx, a steep patch seam) the fixed-point iteration itself
//   converges slowly, so the pixel repeats inverseFlowMap's iterations exactly, from scratch.
class GridInverse {
 public:
  static constexpr float kKinkPx = 0.01f;
  static constexpr float kStrongKinkPx = 0.1f;
  // Slack around a kink segment's image, in nodes: the image curve between two nodes departs from
  // its chord by the inverse's curvature, and inverseFlowMap's camera-resolution sampling spreads a
  // kink over one camera pixel on either side (added per camera size).
  static constexpr float kMarginNodes = 0.25f;
  // Half-width of the band around the border node lines sampled as inverseFlowMap does, pixels.
  static constexpr float kBorderBandPx = 1.5f;
  // Per cell of frame b: the kink work in the low bits, and a flag for cells whose backward
  // positions can come near the border node lines.
  enum CellWork : uchar { kInterpolate = 0, kOneStep = 1, kFullIteration = 2, kKinkMask = 3, kNearBorder = 4 };

  GridInverse(const cv::Mat& flow_grid, cv::Size image_size, int iterations, BackwardMapScratch& scratch)
      : sampler_(flow_grid, image_size),
        reference_(flow_grid, image_size),
        columns_(image_size.width, flow_grid.cols),
        rows_(image_size.height, flow_grid.rows),
        iterations_(iterations),
        horizontal_(scratch.horizontal),
        displacement_(scratch.displacement),
        cell_work_(scratch.cell_work) {
    const cv::Mat& flow = sampler_.flowPx();
    const int w = flow.cols, h = flow.rows;
    const float sx = sampler_.scaleX(), sy = sampler_.scaleY();
    border_x_[0] = 0.5f * sx - 0.5f;
    border_x_[1] = (w - 0.5f) * sx - 0.5f;
    border_y_[0] = 0.5f * sy - 0.5f;
    border_y_[1] = (h - 0.5f) * sy - 0.5f;
    displacement_.create(flow.size(), CV_32FC2);
    // All but the last iteration read the flow with cv::remap (vectorised; positions rounded to
    // 1/32 grid pixel, which moves the flow read by at most its gradient times s/64). The last one
    // samples exactly, and being a contraction it shrinks that error by the flow gradient again.
    // Positions are kept as grid coordinates g = (p + 0.5) / s - 0.5 for cv::remap.
    cv::Mat& position = scratch.position;
    cv::Mat& flow_at_position = scratch.flow_at_position;
    position.create(h, w, CV_32FC2);
    const float inv_sx = 1.0f / sx, inv_sy = 1.0f / sy;
    auto set_positions = [&](const cv::Mat& flow_read) {
      for (int gy = 0; gy < h; ++gy) {
        const cv::Vec2f* f = flow_read.ptr<cv::Vec2f>(gy);
        cv::Vec2f* g = position.ptr<cv::Vec2f>(gy);
        // q - flow in grid coordinates: node - flow / s.
        for (int gx = 0; gx < w; ++gx) g[gx] = cv::Vec2f(gx - f[gx][0] * inv_sx, gy - f[gx][1] * inv_sy);
      }
    };
    set_positions(flow);  // the flow at a node is the grid value: p = q - flow(q) needs no sampling
    for (int i = 0; i + 1 < iterations; ++i) {
      cv::remap(flow, flow_at_position, position, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
      set_positions(flow_at_position);
    }
    for (int gy = 0; gy < h; ++gy) {
      const cv::Vec2f* g = position.ptr<cv::Vec2f>(gy);
      cv::Vec2f* out = displacement_.ptr<cv::Vec2f>(gy);
      for (int gx = 0; gx < w; ++gx) {
        if (iterations == 0) {
          out[gx] = cv::Vec2f((g[gx][0] - gx) * sx, (g[gx][1] - gy) * sy);
          continue;
        }
        float u, v;
        sampler_.sample((g[gx][0] + 0.5f) * sx - 0.5f, (g[gx][1] + 0.5f) * sy - 0.5f, u, v);
        out[gx] = cv::Vec2f(-u, -v);  // p - q = -flow(p)
      }
    }
    interpolateAlongX(image_size.width);
    markKinkCells(flow_grid, kMarginNodes + 1.0f / std::min(sx, sy), scratch);
  }

  const cv::Mat& displacement() const { return displacement_; }

  // The backward positions (camera pixels) of camera rows [row_begin, row_end), handed row by row
  // to `write_row(y, map_xy)` (x, y interleaved): interpolated between nodes, per camera pixel in
  // kink cells. Returns how many pixels were inverted one by one.
  template <typename WriteRow>
  std::size_t buildRows(int row_begin, int row_end, WriteRow write_row) const {
    std::size_t one_by_one = 0;
    const int camera_w = horizontal_.cols;
    const int row_next = horizontal_.rows > 1 ? 1 : 0;
    std::vector<float> map(2 * static_cast<std::size_t>(camera_w));
    float* m = map.data();
    for (int y = row_begin; y < row_end; ++y) {
      // Between the two grid rows already interpolated along x: contiguous, vectorised.
      const float* top = horizontal_.ptr<float>(rows_.lower[y]);
      const float* bottom = horizontal_.ptr<float>(rows_.lower[y] + row_next);
      const float wy = rows_.weight[y], qy = static_cast<float>(y);
      for (int k = 0; k < 2 * camera_w; ++k) m[k] = top[k] + wy * (bottom[k] - top[k]);
      const uchar* work = cell_work_.ptr<uchar>(std::min(rows_.lower[y], cell_work_.rows - 1));
      for (int c = 0; c < cell_work_.cols; ++c) {
        const int kink = work[c] & kKinkMask;
        if (kink == kInterpolate) continue;
        const bool near_border = (work[c] & kNearBorder) != 0;
        for (int x = columns_.first_pixel[c]; x < columns_.first_pixel[c + 1]; ++x) {
          float& px = m[2 * x];
          float& py = m[2 * x + 1];
          if (kink == kFullIteration) {
            reference_.invertAt(x, y, iterations_, px, py);
            continue;
          }
          float u, v;
          sampler_.sample(px, py, u, v);
          px = static_cast<float>(x) - u;
          py = qy - v;
          if (near_border && nearBorderNodeLine(px, py)) reference_.stepAt(x, y, px, py);
        }
        one_by_one += columns_.first_pixel[c + 1] - columns_.first_pixel[c];
      }
      write_row(y, m);
    }
    return one_by_one;
  }

 private:
  // Each grid row of the inverse interpolated along x to camera columns once (cv::resize: the
  // working grid's pixel-centre convention), continued linearly past the outermost nodes (the
  // smooth inverse goes on there; resize holds it constant, which would cost up to a gradient times
  // half a grid cell), stored as positions: x + d_x, and Y + d_y with Y the node row's camera row
  // (y is linear in the rows' blend weight, so blending two of these gives y + d_y). The camera
  // rows then only blend two of these, one vectorised lerp.
  void interpolateAlongX(int camera_w) {
    const int w = displacement_.cols, h = displacement_.rows;
    cv::resize(displacement_, horizontal_, cv::Size(camera_w, h), 0.0, 0.0, cv::INTER_LINEAR);
    for (int gy = 0; gy < h && w >= 2; ++gy) {
      const cv::Vec2f* d = displacement_.ptr<cv::Vec2f>(gy);
      cv::Vec2f* out = horizontal_.ptr<cv::Vec2f>(gy);
      for (int x = 0; x < camera_w && columns_.lower[x] == 0 && columns_.weight[x] < 0.0f; ++x) {
        out[x] = d[0] + columns_.weight[x] * (d[1] - d[0]);
      }
      for (int x = camera_w - 1; x >= 0 && columns_.lower[x] == w - 2 && columns_.weight[x] > 1.0f; --x) {
        out[x] = d[w - 2] + columns_.weight[x] * (d[w - 1] - d[w - 2]);
      }
    }
    const float sy = sampler_.scaleY();
    for (int gy = 0; gy < h; ++gy) {
      const float node_row_px = (gy + 0.5f) * sy - 0.5f;
      cv::Vec2f* out = horizontal_.ptr<cv::Vec2f>(gy);
      for (int x = 0; x < camera_w; ++x) out[x] += cv::Vec2f(static_cast<float>(x), node_row_px);
    }
  }

  // Marks the cells of frame b that a kink of the forward flow passes through (cell_work_).
  // Kinks are the flow's second differences at the nodes, the border continued constant (so the
  // border node lines kink by the flow's slope there). A kink across x at node (X, j) lies on the
  // node line x = X between rows j - 1 and j + 1; its image in frame b (node + flow, grid
  // coordinates) is marked segment by segment, each segment's bounding box widened by `margin`
  // nodes; the segments at the border continue outwards (the flow is constant there).
  void markKinkCells(const cv::Mat& flow_grid, float margin, BackwardMapScratch& scratch) {
    const int w = flow_grid.cols, h = flow_grid.rows;
    const float sx = sampler_.scaleX(), sy = sampler_.scaleY();
    cv::Mat& across_x = scratch.kink_across_x;
    cv::Mat& across_y = scratch.kink_across_y;
    across_x.create(h, w, CV_8U);
    across_y.create(h, w, CV_8U);
    for (int gy = 0; gy < h; ++gy) {
      const cv::Vec2f* row = flow_grid.ptr<cv::Vec2f>(gy);
      const cv::Vec2f* up = flow_grid.ptr<cv::Vec2f>(std::max(gy - 1, 0));
      const cv::Vec2f* down = flow_grid.ptr<cv::Vec2f>(std::min(gy + 1, h - 1));
      uchar* ax = across_x.ptr(gy);
      uchar* ay = across_y.ptr(gy);
      for (int gx = 0; gx < w; ++gx) {
        const cv::Vec2f& left = row[std::max(gx - 1, 0)];
        const cv::Vec2f& right = row[std::min(gx + 1, w - 1)];
        // In camera pixels (the grid flow is in grid pixels).
        const float along_x = std::max(std::abs(left[0] - 2.0f * row[gx][0] + right[0]) * sx,
                                       std::abs(left[1] - 2.0f * row[gx][1] + right[1]) * sy);
        const float along_y = std::max(std::abs(up[gx][0] - 2.0f * row[gx][0] + down[gx][0]) * sx,
                                       std::abs(up[gx][1] - 2.0f * row[gx][1] + down[gx][1]) * sy);
        ax[gx] = static_cast<uchar>((along_x > kKinkPx) + (along_x > kStrongKinkPx));
        ay[gx] = static_cast<uchar>((along_y > kKinkPx) + (along_y > kStrongKinkPx));
      }
    }
    const int cells_x = std::max(1, w - 1), cells_y = std::max(1, h - 1);
    cell_work_.create(cells_y, cells_x, CV_8U);
    cell_work_.setTo(cv::Scalar::all(kInterpolate));
    // The image in frame b of node (gx, gy), grid coordinates.
    auto image = [&](int gx, int gy) {
      const cv::Vec2f& f = flow_grid.at<cv::Vec2f>(gy, gx);
      return cv::Vec2f(gx + f[0], gy + f[1]);
    };
    auto mark = [&](const cv::Vec2f& a, const cv::Vec2f& b, uchar work) {
      const int x0 = std::clamp(cvFloor(std::min(a[0], b[0]) - margin), 0, cells_x - 1);
      const int x1 = std::clamp(cvFloor(std::max(a[0], b[0]) + margin), 0, cells_x - 1);
      const int y0 = std::clamp(cvFloor(std::min(a[1], b[1]) - margin), 0, cells_y - 1);
      const int y1 = std::clamp(cvFloor(std::max(a[1], b[1]) + margin), 0, cells_y - 1);
      for (int cy = y0; cy <= y1; ++cy) {
        uchar* cell = cell_work_.ptr<uchar>(cy);
        for (int cx = x0; cx <= x1; ++cx) cell[cx] = std::max(cell[cx], work);  // before the border flags
      }
    };
    // Kinks across x: segments along y on node column gx; across y: segments along x on node row gy.
    // Past the border nodes the line goes on to the image's edge (the flow is held constant there,
    // so the kink along the line is too): those segments reach beyond every cell.
    const cv::Vec2f beyond_x(static_cast<float>(w + 1), 0.0f), beyond_y(0.0f, static_cast<float>(h + 1));
    for (int gx = 0; gx < w; ++gx) {
      for (int gy = 0; gy + 1 < h; ++gy) {
        const uchar work = std::max(across_x.at<uchar>(gy, gx), across_x.at<uchar>(gy + 1, gx));
        if (work != kInterpolate) mark(image(gx, gy), image(gx, gy + 1), work);
      }
      if (across_x.at<uchar>(0, gx) != kInterpolate) {
        mark(image(gx, 0), image(gx, 0) - beyond_y, across_x.at<uchar>(0, gx));
      }
      if (across_x.at<uchar>(h - 1, gx) != kInterpolate) {
        mark(image(gx, h - 1), image(gx, h - 1) + beyond_y, across_x.at<uchar>(h - 1, gx));
      }
    }
    for (int gy = 0; gy < h; ++gy) {
      const uchar* ay = across_y.ptr(gy);
      for (int gx = 0; gx + 1 < w; ++gx) {
        const uchar work = std::max(ay[gx], ay[gx + 1]);
        if (work != kInterpolate) mark(image(gx, gy), image(gx + 1, gy), work);
      }
      if (ay[0] != kInterpolate) mark(image(0, gy), image(0, gy) - beyond_x, ay[0]);
      if (ay[w - 1] != kInterpolate) mark(image(w - 1, gy), image(w - 1, gy) + beyond_x, ay[w - 1]);
    }
    // The cells whose positions can come within kBorderBandPx of a border node line: around the
    // border nodes' images, a cell and the band (in nodes) wide.
    const float band = kBorderBandPx / std::min(sx, sy) + 1.0f + margin;
    auto flag_border = [&](int gx, int gy) {
      const cv::Vec2f p = image(gx, gy);
      const int x0 = std::clamp(cvFloor(p[0] - band), 0, cells_x - 1), x1 = std::clamp(cvFloor(p[0] + band), 0, cells_x - 1);
      const int y0 = std::clamp(cvFloor(p[1] - band), 0, cells_y - 1), y1 = std::clamp(cvFloor(p[1] + band), 0, cells_y - 1);
      for (int cy = y0; cy <= y1; ++cy) {
        uchar* cell = cell_work_.ptr<uchar>(cy);
        for (int cx = x0; cx <= x1; ++cx) cell[cx] |= kNearBorder;
      }
    };
    for (int gx = 0; gx < w; ++gx) flag_border(gx, 0), flag_border(gx, h - 1);
    for (int gy = 0; gy < h; ++gy) flag_border(0, gy), flag_border(w - 1, gy);
  }

  bool nearBorderNodeLine(float px, float py) const {
    return std::abs(px - border_x_[0]) < kBorderBandPx || std::abs(px - border_x_[1]) < kBorderBandPx ||
           std::abs(py - border_y_[0]) < kBorderBandPx || std::abs(py - border_y_[1]) < kBorderBandPx;
  }

  GridFlowSampler sampler_;
  ReferenceFlowSampler reference_;
  AxisInterpolation columns_, rows_;
  int iterations_;
  cv::Mat& horizontal_;    // CV_32FC2, grid rows x camera columns (scratch)
  cv::Mat& displacement_;  // CV_32FC2 per node: p - q in camera pixels (scratch)
  cv::Mat& cell_work_;     // CellWork per cell of frame b (scratch)
  float border_x_[2], border_y_[2];  // camera positions of the first and last node lines
};

}  // namespace

cv::Mat inverseDisplacementOnGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations) {
  checkInputs(flow_grid, image_size, iterations, "inverseDisplacementOnGrid");
  BackwardMapScratch scratch;
  return GridInverse(flow_grid, image_size, iterations, scratch).displacement();
}

cv::Mat backwardMapFromGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations) {
  checkInputs(flow_grid, image_size, iterations, "backwardMapFromGrid");
  if (cameraWithinGrid(flow_grid, image_size)) return inverseFlowMap(flow_grid, image_size, iterations);
  BackwardMapScratch scratch;
  const GridInverse inverse(flow_grid, image_size, iterations, scratch);
  cv::Mat map(image_size, CV_32FC2);
  inverse.buildRows(0, image_size.height, [&](int y, const float* map_xy) {
    std::copy(map_xy, map_xy + 2 * image_size.width, map.ptr<float>(y));
  });
  return map;
}

void writeFixedPointRow(const float* map_xy, int width, short* xy, ushort* fraction) {
  int x = 0;
#if defined(__SSE2__)
  // Four pixels at a time; _mm_cvtps_epi32 rounds to nearest even, as cvRound does.
  const __m128 scale = _mm_set1_ps(static_cast<float>(kFractionSteps));
  const __m128 low = _mm_set1_ps(-kFarOutsidePx), high = _mm_set1_ps(kFarOutsidePx);
  const __m128i mask = _mm_set1_epi32(kFractionSteps - 1);
  for (; x + 4 <= width; x += 4) {
    const __m128 first = _mm_loadu_ps(map_xy + 2 * x), second = _mm_loadu_ps(map_xy + 2 * x + 4);
    const __m128 mx = _mm_shuffle_ps(first, second, _MM_SHUFFLE(2, 0, 2, 0));
    const __m128 my = _mm_shuffle_ps(first, second, _MM_SHUFFLE(3, 1, 3, 1));
    const __m128i ix = _mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(mx, low), high), scale));
    const __m128i iy = _mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(my, low), high), scale));
    const __m128i whole_x = _mm_srai_epi32(ix, kFractionBits), whole_y = _mm_srai_epi32(iy, kFractionBits);
    const __m128i packed_x = _mm_packs_epi32(whole_x, whole_x), packed_y = _mm_packs_epi32(whole_y, whole_y);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(xy + 2 * x), _mm_unpacklo_epi16(packed_x, packed_y));
    const __m128i table = _mm_or_si128(_mm_slli_epi32(_mm_and_si128(iy, mask), kFractionBits), _mm_and_si128(ix, mask));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(fraction + x), _mm_packs_epi32(table, table));
  }
#endif
  for (; x < width; ++x) {
    // The rounding cv::convertMaps and cv::remap's float path use.
    const int ix = cvRound(std::clamp(map_xy[2 * x], -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
    const int iy = cvRound(std::clamp(map_xy[2 * x + 1], -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
    xy[2 * x] = cv::saturate_cast<short>(ix >> kFractionBits);
    xy[2 * x + 1] = cv::saturate_cast<short>(iy >> kFractionBits);
    fraction[x] = static_cast<ushort>((iy & (kFractionSteps - 1)) * kFractionSteps + (ix & (kFractionSteps - 1)));
  }
}

void buildFixedPointBackwardMap(const cv::Mat& flow_grid, cv::Size image_size, int iterations, FixedPointMap& map) {
  checkInputs(flow_grid, image_size, iterations, "buildFixedPointBackwardMap");
  if (cameraWithinGrid(flow_grid, image_size)) {
    cv::convertMaps(inverseFlowMap(flow_grid, image_size, iterations), cv::noArray(), map.xy, map.fraction, CV_16SC2);
    map.pixels_inverted_one_by_one = static_cast<std::size_t>(image_size.area());
    return;
  }
  if (!map.scratch) map.scratch = std::make_shared<BackwardMapScratch>();
  const GridInverse inverse(flow_grid, image_size, iterations, *map.scratch);
  map.xy.create(image_size, CV_16SC2);
  map.fraction.create(image_size, CV_16UC1);
  auto write_row = [&](int y, const float* map_xy) {
    writeFixedPointRow(map_xy, image_size.width, map.xy.ptr<short>(y), map.fraction.ptr<ushort>(y));
  };
  // One stripe per thread OpenCV may use (one unless cv::setNumThreads allows more).
  const int stripes = std::max(1, std::min(cv::getNumThreads(), image_size.height));
  std::vector<std::size_t> one_by_one(stripes, 0);
  cv::parallel_for_(cv::Range(0, stripes), [&](const cv::Range& range) {
    for (int s = range.start; s < range.end; ++s) {
      one_by_one[s] = inverse.buildRows(image_size.height * s / stripes, image_size.height * (s + 1) / stripes, write_row);
    }
  });
  map.pixels_inverted_one_by_one = 0;
  for (std::size_t count : one_by_one) map.pixels_inverted_one_by_one += count;
}

void warpWithFixedPointMap(const cv::Mat& image, const FixedPointMap& map, cv::Mat& warped) {
  if (image.empty() || image.size() != map.size() || map.xy.type() != CV_16SC2 || map.fraction.type() != CV_16UC1 ||
      map.fraction.size() != map.size()) {
    throw std::invalid_argument("warpWithFixedPointMap: the image and the fixed-point map must have one size");
  }
  cv::remap(image, warped, map.xy, map.fraction, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
}

}  // namespace deep_ois
