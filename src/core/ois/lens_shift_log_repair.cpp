#include "deep_ois/core/ois/lens_shift_log_repair.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

std::string LensShiftLogRepair::summary() const {
  if (repeats_dropped == 0 && steps_back == 0) return "";
  std::ostringstream out;
  out << "lens-shift log: " << repeats_dropped << " repeated sample" << (repeats_dropped == 1 ? "" : "s")
      << " dropped (a copy of an earlier sample within 2 ms, as Android's per-frame batches deliver), "
      << steps_back << " step" << (steps_back == 1 ? "" : "s")
      << " back in file order, sorted; " << samples.size() << " samples kept";
  return out.str();
}

LensShiftLogRepair repairLensShiftLog(const std::vector<LensShiftLogSample>& logged, const std::string& source,
                                      const std::vector<int>& lines, const LensShiftLogRepairOptions& options) {
  LensShiftLogRepair repair;
  auto lineOf = [&](std::size_t k) { return lines.size() == logged.size() ? lines[k] : static_cast<int>(k) + 1; };
  for (std::size_t k = 1; k < logged.size(); ++k) repair.steps_back += logged[k].stamp_s < logged[k - 1].stamp_s;
  // Time order, file order among equal stamps (stable), so the first delivery of a sample is kept.
  std::vector<std::size_t> order(logged.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return logged[a].stamp_s < logged[b].stamp_s; });
  std::vector<bool> dropped(logged.size(), false);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::size_t a = order[i];
    if (dropped[a]) continue;
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      const std::size_t b = order[j];
      if (logged[b].stamp_s - logged[a].stamp_s > options.max_repeat_offset_s) break;
      if (dropped[b] || logged[b].logged != logged[a].logged) continue;
      // The later one in file order is the copy.
      dropped[std::max(a, b)] = true;
      ++repair.repeats_dropped;
      if (b < a) break;  // `a` itself was the copy
    }
  }
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::size_t k = order[i];
    if (dropped[k]) continue;
    if (!repair.samples.empty() && !(logged[k].stamp_s > repair.samples.back().stamp_s)) {
      // Find the kept sample with this stamp for the message.
      std::size_t other = k;
      for (std::size_t j = 0; j < i; ++j)
        if (!dropped[order[j]] && logged[order[j]].stamp_s == logged[k].stamp_s) other = order[j];
      std::ostringstream why;
      why.precision(9);
      why << source << ":" << lineOf(k) << ": stamp " << std::fixed << logged[k].stamp_s
          << " s is also the stamp of line " << lineOf(other)
          << " with a different shift: two lens positions at one instant (not a repeat)";
      throw std::invalid_argument(why.str());
    }
    repair.samples.push_back(logged[k]);
  }
  return repair;
}

}  // namespace deep_ois
