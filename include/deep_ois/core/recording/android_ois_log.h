// A phone's gyro and OIS lens log in the layout of Google's deep-stabilization data (e.g.
// ../shared/data/pixel4_dvs_ois: gyro_log_*.txt, ois_log_*.txt, calib.txt; no frames needed),
// read into what the stabiliser fit uses: the gyro stream and the logged lens positions.
//
// The OIS log arrives in per-frame batches that repeat samples (a stamp microseconds off) and go
// backwards in file order: the reader sorts it and drops a sample within `duplicate_within_s` of
// the previous one, counting what it dropped. Lens positions are in active-array pixels scaled to
// an image `image_width_px` wide (scale = image width / active-array width).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

struct LoggedLensSample {
  double stamp_s = 0.0;
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();
};

struct AndroidOisLog {
  std::vector<CameraRateSample> rates;     // increasing stamps (gyro columns as logged)
  std::vector<LoggedLensSample> lens;      // sorted, repeats removed
  double focal_px = 0.0;                   // image_width_px / calib fov
  std::size_t lens_rows = 0;               // rows read
  std::size_t lens_repeats_dropped = 0;    // within duplicate_within_s of the previous sample
  std::size_t lens_out_of_order = 0;       // rows whose stamp went backwards in file order
  std::size_t gyro_rows_dropped = 0;       // not after the previous gyro stamp
};

struct AndroidOisLogOptions {
  double image_width_px = 4032.0;
  double active_array_width_px = 4032.0;
  int gyro_time_column = 1;  // 1: the first t_us column, 5: the second (logged ~7 ms later)
  double duplicate_within_s = 1e-4;
};

// Reads FOLDER/gyro_log_*.txt, FOLDER/ois_log_*.txt and FOLDER/calib.txt ("fov": sensor width /
// focal length). Throws std::runtime_error naming the file and line of bad input.
AndroidOisLog readAndroidOisLog(const std::string& folder, const AndroidOisLogOptions& options = {});

}  // namespace deep_ois
