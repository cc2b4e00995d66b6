#include "deep_ois/core/recording/android_ois_log.h"

#include <stdexcept>

#include "deep_ois/core/ois/lens_shift_log_repair.h"
#include "deep_ois/core/recording/dvs_log_recording.h"
#include "deep_ois/core/recording/phone_recording.h"

namespace deep_ois {

AndroidOisLog readAndroidOisLog(const std::string& folder, const AndroidOisLogOptions& options) {
  if (!(options.image_width_px > 0.0) || !(options.active_array_width_px > 0.0))
    throw std::invalid_argument("image_width_px and active_array_width_px must be positive");
  const DvsLogFiles files = dvsLogLayout(folder);
  if (files.calib.empty()) throw RecordingFormatError(folder + "/calib.txt", 0, "missing: the focal length comes from its fov");
  const DvsLogRecording recording = loadDvsLogRecording(files);
  AndroidOisLog log;
  log.focal_px = options.image_width_px / recording.fov;
  for (const ImuSample& sample : recording.gyro) log.rates.push_back({sample.stamp_s, sample.angular_velocity_rad_s});
  const LensShiftLogRepair repaired = repairLensShiftLog(recording.ois, files.ois_log, recording.ois_lines);
  const double scale = options.image_width_px / options.active_array_width_px;
  for (const LensShiftLogSample& sample : repaired.samples) log.lens.push_back({sample.stamp_s, scale * sample.logged});
  log.lens_rows = recording.ois.size();
  log.lens_repeats_dropped = static_cast<std::size_t>(repaired.repeats_dropped);
  log.lens_out_of_order = static_cast<std::size_t>(repaired.steps_back);
  return log;
}

}  // namespace deep_ois
