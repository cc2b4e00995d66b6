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
    const int x0 = column_lower_[x], x1 = std::min(x0 + 1, flow_grid_.cols - 1);
    const int y0 = row_lower_[y], y1 = std::min(y0 + 1, flow_grid_.rows - 1);
    const float a = column_weight_[x], b = row_weight_[y];
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

// Everything the map of one pair needs at grid resolution: the inverse at the nodes, and which grid
// cells of frame b hold a kink of the inverse that bilinear interpolation between nodes would
// smooth over (there the map is computed per camera pixel, as inverseFlowMap does).
//
// A kink of the inverse sits where the backward position p crosses a kink of the forward flow. The
// forward flow is bilinear between grid nodes, so it kinks on node lines, by its second difference
// there (a patch seam of the gyro flow, the coarse lattice the network's output is resized from,
// and the border, past which the flow is held constant); interpolating across a kink of second
// difference k errs by up to about k / 4. A cell of frame b whose corners' positions p (with a
// little slack) reach the node line of a kink above kKinkPx is finished per camera pixel:
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
  // The positions inside a cell follow its corners' up to the inverse's curvature: a quarter node
  // of slack covers it.
  static constexpr float kMarginNodes = 0.25f;
  // Half-width of the band around the border node lines sampled as inverseFlowMap does, pixels.
  static constexpr float kBorderBandPx = 1.5f;
  enum CellWork : uchar { kInterpolate = 0, kOneStep = 1, kFullIteration = 2 };

  GridInverse(const cv::Mat& flow_grid, cv::Size image_size, int iterations)
      : sampler_(flow_grid, image_size),
        reference_(flow_grid, image_size),
        columns_(image_size.width, flow_grid.cols),
        rows_(image_size.height, flow_grid.rows),
        iterations_(iterations) {
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
    cv::Mat position(h, w, CV_32FC2), flow_at_position;
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
    // Each grid row interpolated along x to camera columns once (x + d_x, and d_y): the camera rows
    // then only blend two of these.
    horizontal_x_.create(h, image_size.width, CV_32F);
    horizontal_y_.create(h, image_size.width, CV_32F);
    const int next = w > 1 ? 1 : 0;
    for (int gy = 0; gy < h; ++gy) {
      const cv::Vec2f* d = displacement_.ptr<cv::Vec2f>(gy);
      float* hx = horizontal_x_.ptr<float>(gy);
      float* hy = horizontal_y_.ptr<float>(gy);
      for (int x = 0; x < image_size.width; ++x) {
        const int g0 = columns_.lower[x], g1 = g0 + next;
        const float wx = columns_.weight[x];
        hx[x] = static_cast<float>(x) + d[g0][0] + wx * (d[g1][0] - d[g0][0]);
        hy[x] = d[g0][1] + wx * (d[g1][1] - d[g0][1]);
      }
    }
    // Kink nodes (second differences with the border continued constant), as 2-D prefix counts.
    cv::Mat flags[4];  // across x, across y, strong across x, strong across y
    for (cv::Mat& f : flags) f.create(h, w, CV_8U);
    for (int gy = 0; gy < h; ++gy) {
      const cv::Vec2f* row = flow.ptr<cv::Vec2f>(gy);
      const cv::Vec2f* up = flow.ptr<cv::Vec2f>(std::max(gy - 1, 0));
      const cv::Vec2f* down = flow.ptr<cv::Vec2f>(std::min(gy + 1, h - 1));
      uchar* out[4] = {flags[0].ptr(gy), flags[1].ptr(gy), flags[2].ptr(gy), flags[3].ptr(gy)};
      for (int gx = 0; gx < w; ++gx) {
        const cv::Vec2f& left = row[std::max(gx - 1, 0)];
        const cv::Vec2f& right = row[std::min(gx + 1, w - 1)];
        const float along_x = std::max(std::abs(left[0] - 2.0f * row[gx][0] + right[0]),
                                       std::abs(left[1] - 2.0f * row[gx][1] + right[1]));
        const float along_y = std::max(std::abs(up[gx][0] - 2.0f * row[gx][0] + down[gx][0]),
                                       std::abs(up[gx][1] - 2.0f * row[gx][1] + down[gx][1]));
        out[0][gx] = along_x > kKinkPx;
        out[1][gx] = along_y > kKinkPx;
        out[2][gx] = along_x > kStrongKinkPx;
        out[3][gx] = along_y > kStrongKinkPx;
      }
    }
    for (int k = 0; k < 4; ++k) cv::integral(flags[k], kink_counts_[k], CV_32S);
    const bool any_kink = kink_counts_[0].at<int>(h, w) + kink_counts_[1].at<int>(h, w) > 0;
    // Cells of frame b (between nodes c and c + 1 per axis) whose corners' positions enclose a kink.
    const int cells_x = std::max(1, w - 1), cells_y = std::max(1, h - 1);
    cell_needs_pixels_ = cv::Mat::zeros(cells_y, cells_x, CV_8U);
    if (!any_kink) return;
    // Grid position of every node's p = q + d: node + d / s.
    cv::Mat node_position(h, w, CV_32FC2);
    for (int gy = 0; gy < h; ++gy) {
      const cv::Vec2f* d = displacement_.ptr<cv::Vec2f>(gy);
      cv::Vec2f* out = node_position.ptr<cv::Vec2f>(gy);
      for (int gx = 0; gx < w; ++gx) out[gx] = cv::Vec2f(gx + d[gx][0] * inv_sx, gy + d[gx][1] * inv_sy);
    }
    for (int cy = 0; cy < cells_y; ++cy) {
      const cv::Vec2f* upper = node_position.ptr<cv::Vec2f>(cy);
      const cv::Vec2f* lower = node_position.ptr<cv::Vec2f>(std::min(cy + 1, h - 1));
      for (int cx = 0; cx < cells_x; ++cx) {
        const int next = std::min(cx + 1, w - 1);
        const float min_gx = std::min(std::min(upper[cx][0], upper[next][0]), std::min(lower[cx][0], lower[next][0]));
        const float max_gx = std::max(std::max(upper[cx][0], upper[next][0]), std::max(lower[cx][0], lower[next][0]));
        const float min_gy = std::min(std::min(upper[cx][1], upper[next][1]), std::min(lower[cx][1], lower[next][1]));
        const float max_gy = std::max(std::max(upper[cx][1], upper[next][1]), std::max(lower[cx][1], lower[next][1]));
        // The outer half cells of frame b are extrapolated from the border cells: widen those.
        const float left = cx == 0 ? 0.5f : 0.0f, right = cx == cells_x - 1 ? 0.5f : 0.0f;
        const float above = cy == 0 ? 0.5f : 0.0f, below = cy == cells_y - 1 ? 0.5f : 0.0f;
        // A kink across x (second difference along x) lies on the node's vertical line: it counts
        // when the positions straddle that line (none when they all lie beyond the border lines,
        // where the flow is held constant along x); along the other axis, positions beyond the
        // border read the border nodes. Likewise for kinks across y.
        const int straddle_x0 = std::max(cvCeil(min_gx - left - kMarginNodes), 0);
        const int straddle_x1 = std::min(cvFloor(max_gx + right + kMarginNodes), w - 1);
        const int straddle_y0 = std::max(cvCeil(min_gy - above - kMarginNodes), 0);
        const int straddle_y1 = std::min(cvFloor(max_gy + below + kMarginNodes), h - 1);
        const int span_x0 = std::clamp(cvFloor(min_gx - left - kMarginNodes), 0, w - 1);
        const int span_x1 = std::clamp(cvCeil(max_gx + right + kMarginNodes), 0, w - 1);
        const int span_y0 = std::clamp(cvFloor(min_gy - above - kMarginNodes), 0, h - 1);
        const int span_y1 = std::clamp(cvCeil(max_gy + below + kMarginNodes), 0, h - 1);
        auto count = [&](int k, int x0, int x1, int y0, int y1) {
          if (x0 > x1 || y0 > y1) return 0;
          const cv::Mat& prefix = kink_counts_[k];
          return prefix.at<int>(y1 + 1, x1 + 1) - prefix.at<int>(y0, x1 + 1) - prefix.at<int>(y1 + 1, x0) +
                 prefix.at<int>(y0, x0);
        };
        auto kinks = [&](int first) {
          return count(first, straddle_x0, straddle_x1, span_y0, span_y1) +
                 count(first + 1, span_x0, span_x1, straddle_y0, straddle_y1);
        };
        if (kinks(0) > 0) cell_needs_pixels_.at<uchar>(cy, cx) = kinks(2) > 0 ? kFullIteration : kOneStep;
      }
    }
  }

  const cv::Mat& displacement() const { return displacement_; }

  // Writes the backward positions of camera rows [row_begin, row_end) through
  // `write_row(y, map_x, map_y)`: interpolated between nodes, per camera pixel in kink cells.
  cv::Size imageSize() const { return cv::Size(static_cast<int>(columns_.lower.size()), static_cast<int>(rows_.lower.size())); }

  // The backward positions (camera pixels) of camera rows [row_begin, row_end), handed row by row
  // to `write_row(y, map_x, map_y)`: interpolated between nodes, per camera pixel in kink cells.
  // Returns how many pixels were inverted one by one.
  template <typename WriteRow>
  std::size_t buildRows(int row_begin, int row_end, WriteRow write_row) const {
    std::size_t one_by_one = 0;
    const int camera_w = horizontal_x_.cols;
    const int row_next = horizontal_x_.rows > 1 ? 1 : 0;
    std::vector<float> map_x(camera_w), map_y(camera_w);
    for (int y = row_begin; y < row_end; ++y) {
      // Between the two grid rows already interpolated along x: contiguous, vectorised.
      const float* top_x = horizontal_x_.ptr<float>(rows_.lower[y]);
      const float* bottom_x = horizontal_x_.ptr<float>(rows_.lower[y] + row_next);
      const float* top_y = horizontal_y_.ptr<float>(rows_.lower[y]);
      const float* bottom_y = horizontal_y_.ptr<float>(rows_.lower[y] + row_next);
      const float wy = rows_.weight[y], qy = static_cast<float>(y);
      for (int x = 0; x < camera_w; ++x) {
        map_x[x] = top_x[x] + wy * (bottom_x[x] - top_x[x]);
        map_y[x] = qy + top_y[x] + wy * (bottom_y[x] - top_y[x]);
      }
      const uchar* needs_pixels = cell_needs_pixels_.ptr<uchar>(std::min(rows_.lower[y], cell_needs_pixels_.rows - 1));
      for (int c = 0; c < cell_needs_pixels_.cols; ++c) {
        if (needs_pixels[c] == kInterpolate) continue;
        for (int x = columns_.first_pixel[c]; x < columns_.first_pixel[c + 1]; ++x) {
          if (needs_pixels[c] == kFullIteration) {
            reference_.invertAt(x, y, iterations_, map_x[x], map_y[x]);
            continue;
          }
          float u, v;
          sampler_.sample(map_x[x], map_y[x], u, v);
          map_x[x] = static_cast<float>(x) - u;
          map_y[x] = qy - v;
          if (nearBorderNodeLine(map_x[x], map_y[x])) reference_.stepAt(x, y, map_x[x], map_y[x]);
        }
        one_by_one += columns_.first_pixel[c + 1] - columns_.first_pixel[c];
      }
      write_row(y, map_x.data(), map_y.data());
    }
    return one_by_one;
  }

 private:
  GridFlowSampler sampler_;
  ReferenceFlowSampler reference_;
  AxisInterpolation columns_, rows_;
  int iterations_;
  cv::Mat horizontal_x_, horizontal_y_;  // CV_32F, grid rows x camera columns
  cv::Mat displacement_;       // CV_32FC2 per node: p - q in camera pixels
  bool nearBorderNodeLine(float px, float py) const {
    return std::abs(px - border_x_[0]) < kBorderBandPx || std::abs(px - border_x_[1]) < kBorderBandPx ||
           std::abs(py - border_y_[0]) < kBorderBandPx || std::abs(py - border_y_[1]) < kBorderBandPx;
  }

  float border_x_[2], border_y_[2];  // camera positions of the first and last node lines
  // CV_32S (h+1)x(w+1) prefix counts of kink nodes: across x, across y, strong across x, strong
  // across y.
  cv::Mat kink_counts_[4];
  cv::Mat cell_needs_pixels_;  // CellWork per cell of frame b
};

}  // namespace

cv::Mat inverseDisplacementOnGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations) {
  checkInputs(flow_grid, image_size, iterations, "inverseDisplacementOnGrid");
  return GridInverse(flow_grid, image_size, iterations).displacement();
}

cv::Mat backwardMapFromGrid(const cv::Mat& flow_grid, cv::Size image_size, int iterations) {
  checkInputs(flow_grid, image_size, iterations, "backwardMapFromGrid");
  if (cameraWithinGrid(flow_grid, image_size)) return inverseFlowMap(flow_grid, image_size, iterations);
  const GridInverse inverse(flow_grid, image_size, iterations);
  cv::Mat map(image_size, CV_32FC2);
  inverse.buildRows(0, image_size.height, [&](int y, const float* mx, const float* my) {
    cv::Vec2f* out = map.ptr<cv::Vec2f>(y);
    for (int x = 0; x < image_size.width; ++x) out[x] = cv::Vec2f(mx[x], my[x]);
  });
  return map;
}

void buildFixedPointBackwardMap(const cv::Mat& flow_grid, cv::Size image_size, int iterations, FixedPointMap& map) {
  checkInputs(flow_grid, image_size, iterations, "buildFixedPointBackwardMap");
  if (cameraWithinGrid(flow_grid, image_size)) {
    cv::convertMaps(inverseFlowMap(flow_grid, image_size, iterations), cv::noArray(), map.xy, map.fraction, CV_16SC2);
    map.pixels_inverted_one_by_one = static_cast<std::size_t>(image_size.area());
    return;
  }
  const GridInverse inverse(flow_grid, image_size, iterations);
  map.xy.create(image_size, CV_16SC2);
  map.fraction.create(image_size, CV_16UC1);
  auto write_row = [&](int y, const float* mx, const float* my) {
    short* xy = map.xy.ptr<short>(y);
    ushort* fraction = map.fraction.ptr<ushort>(y);
    int x = 0;
#if defined(__SSE2__)
    // Four pixels at a time; _mm_cvtps_epi32 rounds to nearest even, as cvRound does.
    const __m128 scale = _mm_set1_ps(static_cast<float>(kFractionSteps));
    const __m128 low = _mm_set1_ps(-kFarOutsidePx), high = _mm_set1_ps(kFarOutsidePx);
    const __m128i mask = _mm_set1_epi32(kFractionSteps - 1);
    for (; x + 4 <= image_size.width; x += 4) {
      const __m128i ix = _mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(_mm_loadu_ps(mx + x), low), high), scale));
      const __m128i iy = _mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(_mm_loadu_ps(my + x), low), high), scale));
      const __m128i whole_x = _mm_srai_epi32(ix, kFractionBits), whole_y = _mm_srai_epi32(iy, kFractionBits);
      const __m128i packed_x = _mm_packs_epi32(whole_x, whole_x), packed_y = _mm_packs_epi32(whole_y, whole_y);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(xy + 2 * x), _mm_unpacklo_epi16(packed_x, packed_y));
      const __m128i table = _mm_or_si128(_mm_slli_epi32(_mm_and_si128(iy, mask), kFractionBits), _mm_and_si128(ix, mask));
      _mm_storel_epi64(reinterpret_cast<__m128i*>(fraction + x), _mm_packs_epi32(table, table));
    }
#endif
    for (; x < image_size.width; ++x) {
      // The rounding cv::convertMaps and cv::remap's float path use.
      const int ix = cvRound(std::clamp(mx[x], -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
      const int iy = cvRound(std::clamp(my[x], -kFarOutsidePx, kFarOutsidePx) * kFractionSteps);
      xy[2 * x] = cv::saturate_cast<short>(ix >> kFractionBits);
      xy[2 * x + 1] = cv::saturate_cast<short>(iy >> kFractionBits);
      fraction[x] = static_cast<ushort>((iy & (kFractionSteps - 1)) * kFractionSteps + (ix & (kFractionSteps - 1)));
    }
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
