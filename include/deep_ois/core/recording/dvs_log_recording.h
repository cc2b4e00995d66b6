// Google's fused video stabilisation logs ("Deep Online Fused Video Stabilization", the
// deep-stabilization data; ../shared/data/pixel4_dvs_ois): whitespace-separated text files, one
// clock for all three (frames and OIS in ns, gyro in us). Pure core: no ROS.
//   frame_timestamps_*.txt: t_ns exposure_ns ISO readout_ns ois_t_ns zoom frame_id
//   gyro_log_*.txt:         t_us wx wy wz t2_us frame_id   (rad/s, the phone's sensor axes)
//   ois_log_*.txt:          frame_id x y t_ns              (active-array pixels, sensor axes)
//   calib.txt (optional):   JSON with rs_time_us and fov (= sensor width / focal length)
#pragma once

#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

struct DvsLogFiles {
  std::string frame_timestamps, gyro_log, ois_log, calib;  // calib may be empty
};

// The files of a DVS log folder: exactly one frame_timestamps_*.txt, gyro_log_*.txt and
// ois_log_*.txt (calib.txt when present). Throws RecordingFormatError naming what is missing or
// ambiguous.
DvsLogFiles dvsLogLayout(const std::string& directory);

struct DvsLogRecording {
  std::vector<ImuSample> gyro;        // t_us / 1e6, (wx, wy, wz) as logged
  std::vector<double> frame_stamps_s; // t_ns / 1e9 (start of readout), increasing
  std::vector<int> frame_lines;       // 1-based line of each frame stamp
  double readout_s = 0.0;             // the rows' readout_ns (median; they agree on the Pixel 4)
  double exposure_s = 0.0;            // median exposure
  int readout_rows_differing = 0;     // frames whose readout differs from the median by > 1 us
  std::vector<LensShiftLogSample> ois;  // file order (repairLensShiftLog sorts it)
  std::vector<int> ois_lines;
  double fov = 0.0;                   // calib.txt: sensor width / focal length (0: not given)
};

// Reads the files. Throws RecordingFormatError naming the file and line of a malformed row, gyro
// or frame stamps that do not increase, or a calib.txt without a readable fov.
DvsLogRecording loadDvsLogRecording(const DvsLogFiles& files);

}  // namespace deep_ois
