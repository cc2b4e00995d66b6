// The backward map that warps frame a onto frame b when the motion comes as one homography per row
// patch (the gyro's K R K^-1, or a compensator's K(s_b) R K(s_a)^-1 with the lens shifts s) rather
// than as a grid flow: the warp stage's other input beside buildFixedPointBackwardMap.
//
// Convention (the gyro's, rolling_shutter_homographies.h): H_i maps undistorted pixels of frame a
// whose raw row lies in patch i (patchIndexOfRow) to undistorted pixels of frame b; the camera's
// lens distortion, if any, applies on both sides. Pixel q of frame b is therefore reached from
// patch i at p_i = distort(H_i^-1 undistort(q)) when p_i's row lies in patch i. At a seam between
// patches the patches' images can leave a thin gap (no patch reaches q) or overlap (two do); the
// rule, the same in the fast builder and the exact reference:
//   - the lowest-index patch that reaches q;
//   - if none does, the patch whose p_i is nearest to its own rows (lowest index on a tie).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/flow/backward_map.h"

namespace deep_ois {

// The rows of frame a that each patch covers, as continuous raw positions: patch i holds
// y in [lower_px[i], upper_px[i]) (the first patch from -inf, the last to +inf), exactly the rows
// patchIndexOfRow gives i (which rounds y to the nearest row first).
struct PatchRows {
  PatchRows(int image_height_px, int patch_count);
  int count() const { return static_cast<int>(lower_px.size()); }
  bool contains(int patch, double y_px) const { return y_px >= lower_px[patch] && y_px < upper_px[patch]; }
  // Pixels from y to patch `patch`'s rows; 0 inside them.
  double distancePx(int patch, double y_px) const;
  // The documented rule above, given the rows y_px[k] at which the candidate patches
  // `patches[k]` (ascending) reach a pixel. Returns an index into `patches`.
  template <typename Rows>
  std::size_t select(const int* patches, const Rows& y_px, std::size_t candidates) const {
    for (std::size_t k = 0; k < candidates; ++k) {
      if (contains(patches[k], y_px[k])) return k;
    }
    std::size_t best = 0;
    for (std::size_t k = 1; k < candidates; ++k) {
      if (distancePx(patches[k], y_px[k]) < distancePx(patches[best], y_px[best])) best = k;
    }
    return best;
  }

  std::vector<double> lower_px, upper_px;
};

// The exact backward position of pixel q of frame b (camera pixels of frame a), per the rule above,
// every patch evaluated with the camera model's own (iterative) undistortion: the reference of the
// fast builder, slow (microseconds per pixel with distortion). Throws std::invalid_argument when the
// homography count is not the patch count of `rows`.
Eigen::Vector2d exactPatchBackwardPosition(const CameraModel& camera, const std::vector<Eigen::Matrix3d>& homographies,
                                           const PatchRows& rows, const Eigen::Vector2d& q_px);

// Builds the backward map of one camera from its row-patch homographies, fast: each patch's exact
// backward position is computed on a uniform lattice of frame b (every `lattice_step_px` pixels,
// one node before the image and two past it), only for the lattice rows where that patch can be the
// one (decided on a four-times coarser lattice evaluated for every patch, with a margin of one
// lattice step), then interpolated to every pixel with Catmull-Rom cubics, where the rule above
// picks the patch. Within a patch the map is smooth (a homography, the lens distortion on both
// sides), so the automatic lattice stays within 0.01 px of the exact map, a strong barrel distortion
// included (test_patch_homography_map); the seams are resolved per pixel. The camera's undistorted
// lattice is computed once, here.
class PatchHomographyMapBuilder {
 public:
  // lattice_step_px 0: automatic, a 40th of the image width between 4 and 16 pixels (a small image
  // of a wide lens bends fastest per pixel). Throws std::invalid_argument on an invalid camera,
  // patch_count < 1 or a lattice_step_px that is neither 0 nor >= 2.
  PatchHomographyMapBuilder(const CameraModel& camera, int patch_count, int lattice_step_px = 0);

  // `homographies`: patch_count entries, H_i as above. The map in cv::remap's fixed-point form
  // (buffers reused). Throws std::invalid_argument on a wrong count or a non-finite homography.
  void build(const std::vector<Eigen::Matrix3d>& homographies, FixedPointMap& map) const;
  // The same positions as CV_32FC2 (camera pixels of frame a): for tests and tools.
  cv::Mat buildFloat(const std::vector<Eigen::Matrix3d>& homographies) const;

  const CameraModel& camera() const { return camera_; }
  int patchCount() const { return rows_.count(); }
  int latticeStepPx() const { return step_px_; }

 private:
  // Calls write_row(y, map_xy) for every camera row (x, y interleaved).
  template <typename WriteRow>
  void buildRows(const std::vector<Eigen::Matrix3d>& homographies, WriteRow write_row) const;

  CameraModel camera_;
  PatchRows rows_;
  int step_px_;
  std::vector<int> lattice_x_, lattice_y_;            // camera pixels of the lattice columns and rows
  std::vector<Eigen::Vector2d> undistorted_lattice_;  // row-major, lattice_y_.size() x lattice_x_.size()
  std::vector<int> coarse_x_, coarse_y_;              // indices into lattice_x_ / lattice_y_
  // The four cubic weights (nodes -1 .. 2 around a lattice cell) by a pixel's offset in its cell.
  std::vector<float> offset_weights_[4];
};

}  // namespace deep_ois
