// Which decoded video frame belongs to which metadata row of a phone logger. A re-encoded video
// often carries no timing (presentation times a uniform 1/fps) and can have a frame or two more or
// fewer than the logger's rows; one frame of mismatch is a 33 ms time offset that no later
// residual reveals. So the pairing is checked against the gyro: the image motion between
// consecutive frames must rise and fall with the rotation the gyro integrates between the rows'
// stamps. Both are compared as 2-D image motions (x, y pixels), through the 2x2 linear map that
// fits them best (so no sign or axis convention is assumed), and scored by the share of the image
// motion it explains (R^2). Pure core: no ROS.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"

namespace deep_ois {

// Global image motion between consecutive frames: the motion of the image centre under the
// similarity that most corner tracks follow (RANSAC), pixels of the given images; element 0 and
// frames without enough tracks are NaN.
class ConsecutiveImageMotion {
 public:
  // Adds the next frame (8-bit grey); returns its motion from the previous one, px (NaN for the first).
  Eigen::Vector2d add(const cv::Mat& grey);
  const std::vector<Eigen::Vector2d>& motions_px() const { return motions_px_; }

 private:
  cv::Mat previous_;
  std::vector<Eigen::Vector2d> motions_px_;
};

// The gyro's rotation between consecutive stamps as an image motion: (x, y) of the integrated
// rotation in the camera frame times focal_px (small angles; the map to image x, y is fitted by
// pairVideoFrames). Element 0 and stamps the gyro does not cover are NaN.
std::vector<Eigen::Vector2d> gyroImageMotionPx(const std::vector<ImuSample>& gyro, const std::vector<double>& stamps_s,
                                               const Eigen::Matrix3d& imu_to_camera_rotation, double focal_px);

struct VideoFramePairing {
  int shift = 0;  // video frame j is metadata row j - shift
  bool by_presentation_time = false;  // the presentation times carried timing and chose the shift
  std::string timing_note;            // what the presentation times are
  double correlation = 0.0;           // R^2 of the image motion explained by the gyro at `shift`
  int runner_up_shift = 0;
  double runner_up_correlation = 0.0;
  int compared = 0;                   // frame intervals in the correlation
  double log_likelihood_ratio = 0.0;  // of the pairing against the runner-up (Gaussian residuals)
  bool confident = false;             // R^2 >= 0.2 and log-likelihood ratio >= 5
  int video_frames_without_row = 0;
  int rows_without_frame = 0;
  std::string summary() const;        // one paragraph for the user
};

// Tries shifts -max_shift..max_shift. `presentation_s` (per video frame) chose the shift when its
// intervals vary (> 1 ms spread) like the rows'; otherwise (uniform: no timing) the gyro does. The
// gyro check is always made and reported.
VideoFramePairing pairVideoFrames(const std::vector<double>& presentation_s,
                                  const std::vector<Eigen::Vector2d>& image_motion_px,
                                  const std::vector<double>& row_stamps_s,
                                  const std::vector<Eigen::Vector2d>& gyro_motion_px, int max_shift = 5);

}  // namespace deep_ois
