// Puts a lens-shift log as a phone delivers it into time order. Android delivers OisSample[] in
// per-frame batches, and a batch can start with a copy of the previous batch's last sample whose
// stamp is off by microseconds (up to about a millisecond on some phones): in file order the stamps
// then step back. Such copies carry no information (same shift, nearly the same instant) and would
// make LensShiftLog refuse the log, so they are dropped and counted. Pure core: no ROS.
#pragma once

#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

struct LensShiftLogRepairOptions {
  // A sample with exactly the shift of an earlier (in file order) sample whose stamp lies within
  // this many seconds is a repeat. 2 ms: above the ~1 ms of the worst phone seen, below the 5 ms
  // between samples of a 200 Hz log (a real sample 5 ms later with an equal shift is kept).
  double max_repeat_offset_s = 0.002;
};

struct LensShiftLogRepair {
  std::vector<LensShiftLogSample> samples;  // strictly increasing stamps
  int repeats_dropped = 0;    // copies of an earlier sample, left out
  int steps_back = 0;         // times a stamp was earlier than the one before it, in file order
  // One sentence for the user ("" when nothing was changed).
  std::string summary() const;
};

// Sorts `logged` (file order) by stamp and drops the repeats. `source` and `lines` (the 1-based
// line of each sample, same size as `logged`, or empty) only label the error. Throws
// std::invalid_argument naming both lines when two samples share a stamp but not a shift (no
// order between them can be right).
LensShiftLogRepair repairLensShiftLog(const std::vector<LensShiftLogSample>& logged, const std::string& source,
                                      const std::vector<int>& lines = {},
                                      const LensShiftLogRepairOptions& options = {});

}  // namespace deep_ois
