// A one-line terminal progress bar with rate and ETA for the offline tools. On a terminal it is
// redrawn in place; into a redirected stderr (a log file, a CI job) carriage-return redraws are
// noise, so a file gets whole lines instead: the first update, one every 10 s and the last.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace deep_ois {

class ProgressBar {
 public:
  // `unit` names what is counted ("frames", "pairs"); output goes to `stream` (stderr by default,
  // so stdout stays clean for results; nullptr: nowhere).
  ProgressBar(std::size_t total, std::string unit, std::FILE* stream = stderr);

  // The total once it is known (a job that counts its work after it started): the clock, and so
  // the rate, keeps running from the construction.
  void setTotal(std::size_t total) { total_ = total; }
  // True when update() redraws in place (the stream is a terminal). A tool that prints between
  // updates starts its line with a newline only then.
  bool drawing() const { return drawing_; }

  // Reports `done` items; redraws at most every 0.2 s on a terminal (a whole line every 10 s into a
  // file), and always at the end. A non-empty `note`
  // (e.g. "epoch 3/40, loss 0.21") is appended to the line.
  void update(std::size_t done, const std::string& note = "");
  // The line as it would be drawn (for tests): "[#####     ] 5/10 frames, 2.0 frames/s, ETA 3 s".
  // The rate and the ETA are "?" for the first half second: a rate over a shorter span (the first
  // item done right after the bar was made) is noise, not a rate.
  std::string line(std::size_t done, double elapsed_s) const;
  double elapsedSeconds() const;

 private:
  std::size_t total_;
  std::string unit_;
  std::FILE* stream_;
  bool drawing_ = false;
  std::chrono::steady_clock::time_point started_;
  double last_draw_s_ = -1.0;
  bool finished_ = false;  // the last line was drawn
};

}  // namespace deep_ois
