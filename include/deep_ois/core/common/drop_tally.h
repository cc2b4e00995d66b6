// Counts of dropped work by reason, for one throttled warning that says how many and why.
//
// Why: a per-message warning throttled to one every few seconds hides how many messages were
// lost and for which reasons; a tally summarises everything since the last warning, so nothing
// dropped goes unsaid, and totals since start stay available for diagnostics.
#pragma once

#include <cstddef>
#include <map>
#include <sstream>
#include <string>

namespace deep_ois {

class DropTally {
 public:
  void add(const std::string& reason, std::size_t count = 1) {
    since_report_[reason] += count;
    total_ += count;
  }
  // Dropped since start (or since the last clear()).
  std::size_t total() const { return total_; }
  // Something was dropped since the last take().
  bool pending() const { return !since_report_.empty(); }
  std::size_t pendingCount() const {
    std::size_t n = 0;
    for (const auto& r : since_report_) n += r.second;
    return n;
  }
  // "2 (its frame never came), 1 (too many flows waiting)": the counts since the last take(),
  // which are then forgotten.
  std::string take() {
    std::ostringstream text;
    bool first = true;
    for (const auto& r : since_report_) {
      text << (first ? "" : ", ") << r.second << " (" << r.first << ")";
      first = false;
    }
    since_report_.clear();
    return text.str();
  }
  void clear() {
    since_report_.clear();
    total_ = 0;
  }

 private:
  std::map<std::string, std::size_t> since_report_;
  std::size_t total_ = 0;
};

}  // namespace deep_ois
