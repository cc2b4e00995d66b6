#include "deep_ois/core/flow/patch_homography_map.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace deep_ois {
namespace {

// Where a position that no homography can reach (behind the camera) is put: far outside frame a,
// so the warp reads black there (writeFixedPointRow clamps it to its own limit).
constexpr double kUnreachablePx = -1.0e6;
// The coarse lattice that picks the patches per lattice row: every kCoarseEvery-th lattice node.
constexpr int kCoarseEvery = 4;

// A uniform lattice -step, 0, step, ... reaching two steps past the last pixel: every pixel has two
// nodes on either side for the cubic interpolation.
std::vector<int> latticeCoordinates(int pixels, int step) {
  std::vector<int> coordinates;
  for (int k = 0; k < (pixels - 1) / step + 4; ++k) coordinates.push_back((k - 1) * step);
  return coordinates;
}

// Catmull-Rom weights of the nodes at -1, 0, 1, 2 for a position t in [0, 1) between nodes 0 and
// 1: exact for cubic polynomials, so the lattice interpolation errs by the map's fourth derivative
// (bilinear interpolation erred by the second, 0.09 px on a strong barrel distortion at 16 px).
void cubicWeights(float t, float* w) {
  const float t2 = t * t, t3 = t2 * t;
  w[0] = 0.5f * (-t3 + 2.0f * t2 - t);
  w[1] = 0.5f * (3.0f * t3 - 5.0f * t2 + 2.0f);
  w[2] = 0.5f * (-3.0f * t3 + 4.0f * t2 + t);
  w[3] = 0.5f * (t3 - t2);
}

// Every kCoarseEvery-th index of a lattice axis of `count` nodes, and the last.
std::vector<int> coarseIndices(int count) {
  std::vector<int> indices;
  for (int i = 0; i < count - 1; i += kCoarseEvery) indices.push_back(i);
  indices.push_back(count - 1);
  return indices;
}

// Frame a's undistorted position H^-1 u, or an unreachable one when u maps behind the camera.
Eigen::Vector2d inverseMapped(const Eigen::Matrix3d& inverse, const Eigen::Vector2d& u) {
  const Eigen::Vector3d p = inverse * u.homogeneous();
  if (!(p.z() > 0.0)) return Eigen::Vector2d(kUnreachablePx, kUnreachablePx);
  return p.hnormalized();
}

std::vector<Eigen::Matrix3d> inverses(const std::vector<Eigen::Matrix3d>& homographies, int patch_count,
                                      const char* caller) {
  if (static_cast<int>(homographies.size()) != patch_count) {
    throw std::invalid_argument(std::string(caller) + ": got " + std::to_string(homographies.size()) +
                                " homographies for " + std::to_string(patch_count) + " patches");
  }
  std::vector<Eigen::Matrix3d> result;
  for (const Eigen::Matrix3d& H : homographies) {
    Eigen::FullPivLU<Eigen::Matrix3d> lu(H);
    if (!H.allFinite() || !lu.isInvertible()) {
      throw std::invalid_argument(std::string(caller) + ": a homography is not finite or not invertible");
    }
    result.push_back(lu.inverse());
  }
  return result;
}

// Distorted positions, with the distortion's own non-finite results (far outside its domain) made
// unreachable too.
void distortInPlace(const CameraModel& camera, std::vector<Eigen::Vector2d>& points) {
  camera.distortPoints(points);
  for (Eigen::Vector2d& p : points) {
    if (!p.allFinite()) p = Eigen::Vector2d(kUnreachablePx, kUnreachablePx);
  }
}

}  // namespace

PatchRows::PatchRows(int image_height_px, int patch_count) {
  if (image_height_px < 1 || patch_count < 1) {
    throw std::invalid_argument("PatchRows: the image height and the patch count must be positive");
  }
  const double infinity = std::numeric_limits<double>::infinity();
  for (int i = 0; i < patch_count; ++i) {
    // Integer rows r with floor(r * N / h) == i: from ceil(i h / N) to ceil((i + 1) h / N) - 1.
    const long long h = image_height_px, n = patch_count;
    const double first = static_cast<double>((i * h + n - 1) / n);
    const double end = static_cast<double>(((i + 1) * h + n - 1) / n);
    lower_px.push_back(i == 0 ? -infinity : first - 0.5);
    upper_px.push_back(i == patch_count - 1 ? infinity : end - 0.5);
  }
}

double PatchRows::distancePx(int patch, double y_px) const {
  if (y_px < lower_px[patch]) return lower_px[patch] - y_px;
  if (y_px >= upper_px[patch]) return y_px - upper_px[patch];
  return 0.0;
}

Eigen::Vector2d exactPatchBackwardPosition(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& homographies,
                                           const PatchRows& rows, const Eigen::Vector2d& q_px) {
  const std::vector<Eigen::Matrix3d> inverse = inverses(homographies, rows.count(), "exactPatchBackwardPosition");
  const Eigen::Vector2d u = camera.undistort(q_px);
  std::vector<Eigen::Vector2d> positions;
  for (const Eigen::Matrix3d& G : inverse) positions.push_back(inverseMapped(G, u));
  distortInPlace(camera, positions);
  std::vector<int> patches(positions.size());
  std::vector<double> y_px(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) patches[i] = static_cast<int>(i), y_px[i] = positions[i].y();
  return positions[rows.select(patches.data(), y_px, positions.size())];
}

PatchHomographyMapBuilder::PatchHomographyMapBuilder(const CameraModel& camera, int patch_count, int lattice_step_px)
    : camera_(camera),
      rows_(std::max(camera.height(), 1), std::max(patch_count, 1)),
      step_px_(lattice_step_px == 0 ? std::clamp(camera.width() / 40, 4, 16) : lattice_step_px) {
  const std::string problem = camera.validate();
  if (!problem.empty()) throw std::invalid_argument("PatchHomographyMapBuilder: " + problem);
  if (patch_count < 1) throw std::invalid_argument("PatchHomographyMapBuilder: patch_count must be >= 1");
  if (lattice_step_px != 0 && lattice_step_px < 2) {
    throw std::invalid_argument("PatchHomographyMapBuilder: lattice_step_px must be 0 (automatic) or >= 2");
  }
  lattice_x_ = latticeCoordinates(camera.width(), step_px_);
  lattice_y_ = latticeCoordinates(camera.height(), step_px_);
  for (int y : lattice_y_) {
    for (int x : lattice_x_) undistorted_lattice_.emplace_back(x, y);
  }
  camera.undistortPoints(undistorted_lattice_);  // once per camera: the iterative part
  coarse_x_ = coarseIndices(static_cast<int>(lattice_x_.size()));
  coarse_y_ = coarseIndices(static_cast<int>(lattice_y_.size()));
  for (auto& weights : offset_weights_) weights.resize(step_px_);
  for (int t = 0; t < step_px_; ++t) {
    float w[4];
    cubicWeights(static_cast<float>(t) / static_cast<float>(step_px_), w);
    for (int j = 0; j < 4; ++j) offset_weights_[j][t] = w[j];
  }
}

template <typename WriteRow>
void PatchHomographyMapBuilder::buildRows(const std::vector<Eigen::Matrix3d>& homographies, WriteRow write_row) const {
  const std::vector<Eigen::Matrix3d> inverse = inverses(homographies, rows_.count(), "PatchHomographyMapBuilder");
  const int patches = rows_.count();
  const int nx = static_cast<int>(lattice_x_.size()), ny = static_cast<int>(lattice_y_.size());
  const int width = camera_.width(), height = camera_.height();

  // 1. Every patch on the coarse lattice: which lattice rows each patch can be the one for.
  std::vector<Eigen::Vector2d> coarse;
  for (int i = 0; i < patches; ++i) {
    for (int cy : coarse_y_) {
      for (int cx : coarse_x_) coarse.push_back(inverseMapped(inverse[i], undistorted_lattice_[cy * nx + cx]));
    }
  }
  distortInPlace(camera_, coarse);
  std::vector<std::vector<char>> needed(patches, std::vector<char>(ny, 0));
  const std::size_t coarse_per_patch = coarse_y_.size() * coarse_x_.size();
  for (int i = 0; i < patches; ++i) {
    for (std::size_t k = 0; k + 1 < coarse_y_.size() || (coarse_y_.size() == 1 && k == 0); ++k) {
      double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
      for (std::size_t r = k; r <= std::min(k + 1, coarse_y_.size() - 1); ++r) {
        for (std::size_t c = 0; c < coarse_x_.size(); ++c) {
          const double y = coarse[i * coarse_per_patch + r * coarse_x_.size() + c].y();
          lowest = std::min(lowest, y);
          highest = std::max(highest, y);
        }
      }
      // Within a lattice step of the patch's rows: the patch may be the one, or the nearest one
      // across a gap at a seam.
      if (highest + step_px_ < rows_.lower_px[i] || lowest - step_px_ >= rows_.upper_px[i]) continue;
      const int last = coarse_y_[std::min(k + 1, coarse_y_.size() - 1)];
      for (int r = coarse_y_[k]; r <= last; ++r) needed[i][r] = 1;
    }
  }
  // A lattice cell row no patch claims (everything far off): every patch there, the rule decides.
  for (int r = 0; r + 1 < ny || (ny == 1 && r == 0); ++r) {
    const int next = std::min(r + 1, ny - 1);
    bool any = false;
    for (int i = 0; i < patches; ++i) any = any || (needed[i][r] && needed[i][next]);
    if (!any) {
      for (int i = 0; i < patches; ++i) needed[i][r] = needed[i][next] = 1;
    }
  }

  // The cubic interpolation between rows r and r + 1 also reads rows r - 1 and r + 2.
  for (int i = 0; i < patches; ++i) {
    std::vector<char> grown = needed[i];
    for (int r = 0; r < ny; ++r) {
      if (needed[i][r]) grown[std::max(r - 1, 0)] = grown[std::min(r + 1, ny - 1)] = 1;
    }
    needed[i].swap(grown);
  }

  // 2. The needed lattice rows of each patch, exactly (one distortion call for all of them).
  std::vector<Eigen::Vector2d> points;
  std::vector<std::vector<int>> offset(patches, std::vector<int>(ny, -1));
  for (int i = 0; i < patches; ++i) {
    for (int r = 0; r < ny; ++r) {
      if (!needed[i][r]) continue;
      offset[i][r] = static_cast<int>(points.size());
      for (int c = 0; c < nx; ++c) points.push_back(inverseMapped(inverse[i], undistorted_lattice_[r * nx + c]));
    }
  }
  distortInPlace(camera_, points);
  std::vector<float> lattice_values(2 * points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    lattice_values[2 * k] = static_cast<float>(points[k].x());
    lattice_values[2 * k + 1] = static_cast<float>(points[k].y());
  }

  // 3. Per camera row: each candidate patch interpolated, the rule where there are several.
  std::vector<float> node_row(2 * static_cast<std::size_t>(nx));
  std::vector<std::vector<float>> candidate_rows(patches, std::vector<float>(2 * static_cast<std::size_t>(width)));
  std::vector<int> candidates;
  int candidates_cell = -1;
  std::vector<double> candidate_y(patches);
  std::vector<float> out(2 * static_cast<std::size_t>(width));
  for (int y = 0; y < height; ++y) {
    const int cell = y / step_px_ + 1;  // node row 1 is pixel row 0
    float wy[4];
    cubicWeights(static_cast<float>(y % step_px_) / static_cast<float>(step_px_), wy);
    if (cell != candidates_cell) {
      // The patches that can be the one in this lattice cell row: their rows within half a lattice
      // step (gaps at seams are narrower) of the positions at the cell row's nodes.
      candidates_cell = cell;
      candidates.clear();
      for (int i = 0; i < patches; ++i) {
        if (offset[i][cell] < 0 || offset[i][cell + 1] < 0) continue;
        float lowest = std::numeric_limits<float>::infinity(), highest = -lowest;
        for (int r = cell; r <= cell + 1; ++r) {
          const float* values = &lattice_values[2 * static_cast<std::size_t>(offset[i][r])];
          for (int c = 0; c < nx; ++c) lowest = std::min(lowest, values[2 * c + 1]), highest = std::max(highest, values[2 * c + 1]);
        }
        const double margin_px = 0.5 * step_px_ + 1.0;
        if (highest + margin_px >= rows_.lower_px[i] && lowest - margin_px < rows_.upper_px[i]) candidates.push_back(i);
      }
      if (candidates.empty()) {
        for (int i = 0; i < patches; ++i) {
          if (offset[i][cell] >= 0 && offset[i][cell + 1] >= 0) candidates.push_back(i);
        }
      }
    }
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const int i = candidates[k];
      const float* lattice_rows[4];
      for (int j = 0; j < 4; ++j) {
        lattice_rows[j] = &lattice_values[2 * static_cast<std::size_t>(offset[i][cell - 1 + j])];
      }
      for (int c = 0; c < 2 * nx; ++c) {
        node_row[c] = wy[0] * lattice_rows[0][c] + wy[1] * lattice_rows[1][c] + wy[2] * lattice_rows[2][c] +
                      wy[3] * lattice_rows[3][c];
      }
      float* row = candidates.size() == 1 ? out.data() : candidate_rows[k].data();
      // Lattice cell by cell (pixels x0 .. x0 + step - 1, node 1 being pixel 0): four fixed nodes,
      // weights by the offset in the cell, a loop the compiler vectorises.
      const float *w0 = offset_weights_[0].data(), *w1 = offset_weights_[1].data();
      const float *w2 = offset_weights_[2].data(), *w3 = offset_weights_[3].data();
      for (int x0 = 0; x0 < width; x0 += step_px_) {
        const float* n = &node_row[2 * static_cast<std::size_t>(x0 / step_px_)];
        const int pixels = std::min(step_px_, width - x0);
        float* r = row + 2 * x0;
        for (int t = 0; t < pixels; ++t) {
          r[2 * t] = w0[t] * n[0] + w1[t] * n[2] + w2[t] * n[4] + w3[t] * n[6];
          r[2 * t + 1] = w0[t] * n[1] + w1[t] * n[3] + w2[t] * n[5] + w3[t] * n[7];
        }
      }
    }
    if (candidates.size() > 1) {
      for (int x = 0; x < width; ++x) {
        for (std::size_t k = 0; k < candidates.size(); ++k) candidate_y[k] = candidate_rows[k][2 * x + 1];
        const std::size_t chosen = rows_.select(candidates.data(), candidate_y, candidates.size());
        out[2 * x] = candidate_rows[chosen][2 * x];
        out[2 * x + 1] = candidate_rows[chosen][2 * x + 1];
      }
    }
    write_row(y, out.data());
  }
}

void PatchHomographyMapBuilder::build(const std::vector<Eigen::Matrix3d>& homographies, FixedPointMap& map) const {
  const cv::Size size(camera_.width(), camera_.height());
  map.xy.create(size, CV_16SC2);
  map.fraction.create(size, CV_16UC1);
  buildRows(homographies, [&](int y, const float* map_xy) {
    writeFixedPointRow(map_xy, size.width, map.xy.ptr<short>(y), map.fraction.ptr<ushort>(y));
  });
  map.pixels_inverted_one_by_one = 0;
}

cv::Mat PatchHomographyMapBuilder::buildFloat(const std::vector<Eigen::Matrix3d>& homographies) const {
  cv::Mat map(camera_.height(), camera_.width(), CV_32FC2);
  buildRows(homographies, [&](int y, const float* map_xy) {
    std::copy(map_xy, map_xy + 2 * map.cols, map.ptr<float>(y));
  });
  return map;
}

}  // namespace deep_ois
