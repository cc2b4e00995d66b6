#include "deep_ois/tools/support/recording_conversion_report.h"

#include "deep_ois/core/common/printf_text.h"
#include "deep_ois/tools/support/stabiliser_training_report.h"

namespace deep_ois {

std::vector<std::string> conversionSummary(const std::string& bag_path, const PhoneRecordingBagStats& stats,
                                           double wall_time_s) {
  std::vector<std::string> lines;
  std::string written = bag_path + ": " + countOf(stats.frames, "frame", "frames");
  if (!stats.images) written += " without images (camera_info only)";
  written += " (indices " + std::to_string(stats.first_frame_index) + ".." +
             std::to_string(stats.last_frame_index) + ", " +
             (stats.skipped_frame_indices > 0 ? countOf(stats.skipped_frame_indices, "index", "indices") + " missing"
                                              : std::string("none missing")) +
             ") " + std::to_string(stats.width_px) + "x" + std::to_string(stats.height_px) +
             (stats.images ? " " + stats.encoding : std::string()) + ", " + countOf(stats.imu_messages, "IMU message", "IMU messages") + ", " +
             countOf(stats.lens_shift_messages, "lens-shift sample", "lens-shift samples");
  lines.push_back(written);
  const double span_s = (stats.last_frame_stamp - stats.first_frame_stamp).toSec();
  lines.push_back(printfText("frame stamps: first %u.%09u s, last %u.%09u s (the bag's clock), %.1f s of "
                             "recording between them",
                             stats.first_frame_stamp.sec, stats.first_frame_stamp.nsec, stats.last_frame_stamp.sec,
                             stats.last_frame_stamp.nsec, span_s));
  if (stats.dropped_uncovered_frames > 0)
    lines.push_back(countOf(stats.dropped_uncovered_frames, "frame", "frames") +
                    " the gyro does not cover left out (--drop-uncovered-frames)");
  if (stats.frames_outside_span > 0)
    lines.push_back(countOf(stats.frames_outside_span, "frame", "frames") + " outside --from/--to left out");
  if (stats.lens_shift_repeats_dropped > 0 || stats.lens_shift_steps_back > 0) {
    lines.push_back("lens-shift log: " +
                    countOf(stats.lens_shift_repeats_dropped, "repeated sample", "repeated samples") +
                    " dropped (a copy of an earlier sample within 2 ms: Android's per-frame OIS batches), " +
                    countOf(stats.lens_shift_steps_back, "step", "steps") + " back in file order, sorted");
  }
  lines.push_back(printfText("converted in %.1f s (wall time: reading, pairing and writing)", wall_time_s));
  return lines;
}

}  // namespace deep_ois
