// A row of the evaluation table: a way to align frame b of a pair with frame a. The evaluator
// (tools/support/evaluation_runner.h) hands every method the same frame pair context and scores whatever
// motion it returns with the one geometry distance (geometry_distance.h), capped at identity.
//
// Adding a method is a name, the pairs it applies to and a function; e.g. a network that maps the
// gyro flow grid to a compensated flow grid (pairs come in recording order, so a method may keep
// state across them, as the network's motion history does):
//
//   runner.addMethod({"DeepOIS (shipped model)", kOisCameraPairs,
//                     [&stream](const FramePairContext& pair) {
//                       return AlignmentEstimate::gridFlow(
//                           stream.compensate(pair.gyro_flow_grid, pair.stamp_a_ns, pair.stamp_b_ns));
//                     }});
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"

namespace deep_ois {

// Which recordings a pair comes from, as bit flags; a method scores the pairs its scope includes.
enum PairScope : unsigned {
  kOisCameraPairs =
      1u,  // an OIS camera: simulator bags with OIS on, or annotated recordings said to be OIS
  kNonOisCameraPairs = 2u,       // annotated recordings said to be without OIS
  kUnspecifiedCameraPairs = 4u,  // annotated recordings whose OIS state is not given
  kNonOisTwinPairs = 8u,  // simulator non-OIS twins: they exist only for the gyro reference row
  kBenchmarkPairs = kOisCameraPairs | kNonOisCameraPairs | kUnspecifiedCameraPairs,
};

// Everything a method may look at for one frame pair a -> b. Owned by the evaluator and valid
// during the call; images are shared, not copied: methods must not modify them.
struct FramePairContext {
  std::uint64_t recording_id = 0;  // unique per recording in one run (for caches keyed by frame)
  std::int64_t stamp_a_ns = 0;     // header stamps of the frames, nanoseconds since the epoch
  std::int64_t stamp_b_ns = 0;
  std::string category;
  PairScope scope = kOisCameraPairs;
  const CameraModel* camera = nullptr;  // the recording's camera_info
  cv::Mat rgb_a, rgb_b;                 // CV_8UC3, RGB order, camera size
  cv::Mat gray_a, gray_b;               // CV_8UC1
  // The gyro flow nodelet's output for this pair (same code, same config/gyro_flow.yaml): N row
  // patch homographies between undistorted camera pixels, and the CV_32FC2 flow on the working
  // grid (grid_flow.h convention) that the nodelet publishes and the network takes as input.
  std::vector<Eigen::Matrix3d> gyro_homographies;
  cv::Mat gyro_flow_grid;
  // The gyro stream behind them, for methods that carry a stabiliser's state (core/ois/): the
  // recording's IMU samples, the gyro flow's rolling-shutter config (IMU -> camera rotation, time
  // offset, readout, patches), the frames' stamps in the IMU buffer's time base (seconds, camera
  // clock: patchImuTime() maps them) and the gyro's rotation R_b_a per patch.
  const ImuSampleBuffer* imu = nullptr;
  const RollingShutterConfig* rolling_shutter = nullptr;
  double stamp_a_s = 0.0, stamp_b_s = 0.0;
  std::vector<Eigen::Matrix3d> gyro_rotations;
  // The gyro flow nodelet's homographies with the camera's lens-shift log,
  // K(s(t_b)) R K(s(t_a))^-1 per patch, when the recording has a log that covers the pair; empty
  // otherwise (core/ois/lens_shift_homographies.h).
  std::vector<Eigen::Matrix3d> lens_log_homographies;
  // The correspondences the pair is scored on (raw pixels). Methods other than references must
  // not use them.
  std::vector<Eigen::Vector2d> points_a_px, points_b_px;
};

// A method's answer for one pair.
struct AlignmentEstimate {
  enum class Kind {
    kFailed,        // no motion (too few matches, solver failure): scored as identity and counted
    kHomographies,  // one homography (global) or N row patch homographies, camera pixels
    kGridFlow,      // a dense CV_32FC2 flow on a working grid (grid_flow.h convention)
  };
  Kind kind = Kind::kFailed;
  std::string failure_reason;
  // kHomographies: patch i holds rows [i*h/N, (i+1)*h/N) of frame a (N = 1: one for the frame).
  std::vector<Eigen::Matrix3d> homographies;
  // true: they map undistorted pixels (rotation models K R K^-1), and the camera's distortion is
  // applied around them as the gyro flow does; false: they map raw image pixels (image matching).
  bool undistorted_pixels = false;
  cv::Mat grid_flow;

  static AlignmentEstimate failed(const std::string& reason);
  static AlignmentEstimate rawHomography(const Eigen::Matrix3d& H);
  static AlignmentEstimate patchHomographies(
      const std::vector<Eigen::Matrix3d>& homographies_undistorted);
  static AlignmentEstimate gridFlow(const cv::Mat& flow);
  bool ok() const { return kind != Kind::kFailed; }
};

struct AlignmentMethod {
  std::string name;                  // the table row
  unsigned scope = kBenchmarkPairs;  // PairScope flags of the pairs it scores
  // Called once per pair in scope, from one thread, pairs in recording order. May throw: the
  // evaluator records the message as that pair's failure.
  std::function<AlignmentEstimate(const FramePairContext&)> estimate;
};

// The geometry distance of an estimate on the pair's correspondences (pixels); NaN for a failed
// estimate. Throws std::invalid_argument on a malformed estimate (no homography, bad flow).
double estimateDistance(const AlignmentEstimate& estimate, const FramePairContext& pair);

// The estimate as a dense flow at camera resolution, in camera pixels (CV_32FC2), for warping
// frame b onto frame a; a failed estimate gives a zero flow (identity).
cv::Mat estimateCameraFlow(const AlignmentEstimate& estimate, const CameraModel& camera);

}  // namespace deep_ois
