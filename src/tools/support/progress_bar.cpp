#include "deep_ois/tools/support/progress_bar.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace deep_ois {

namespace {
constexpr int kBarWidth = 30;
constexpr double kRedrawPeriodS = 0.2;
// Into a file: a line this often (seconds), besides the first and the last.
constexpr double kFileLinePeriodS = 10.0;
// A rate measured over less time than this is not shown (seconds).
constexpr double kMinimumRateSpanS = 0.5;
}  // namespace

ProgressBar::ProgressBar(std::size_t total, std::string unit, std::FILE* stream)
    : total_(total),
      unit_(std::move(unit)),
      stream_(stream),
      drawing_(stream != nullptr && isatty(fileno(stream)) == 1),
      started_(std::chrono::steady_clock::now()) {}

double ProgressBar::elapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
}

std::string ProgressBar::line(std::size_t done, double elapsed_s) const {
  const double fraction = total_ > 0 ? std::min(1.0, static_cast<double>(done) / total_) : 1.0;
  const int filled = static_cast<int>(std::floor(fraction * kBarWidth));
  const bool rate_known = elapsed_s >= kMinimumRateSpanS;
  const double rate = rate_known ? done / elapsed_s : 0.0;
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(1);
  out << "[" << std::string(filled, '#') << std::string(kBarWidth - filled, ' ') << "] " << done
      << "/" << total_ << " " << unit_ << ", ";
  if (rate_known) {
    out << rate;
  } else {
    out << "?";
  }
  out << " " << unit_ << "/s, ETA ";
  if (rate > 0.0) {
    out.precision(0);
    out << (total_ > done ? (total_ - done) / rate : 0.0) << " s";
  } else {
    out << "?";
  }
  return out.str();
}

void ProgressBar::update(std::size_t done, const std::string& note) {
  if (stream_ == nullptr || (finished_ && done >= total_)) return;
  const double elapsed = elapsedSeconds();
  const bool finished = done >= total_;
  const double period = drawing_ ? kRedrawPeriodS : kFileLinePeriodS;
  if (!finished && last_draw_s_ >= 0.0 && elapsed - last_draw_s_ < period) return;
  last_draw_s_ = elapsed;
  finished_ = finished;
  const std::string text = note.empty() ? line(done, elapsed) : line(done, elapsed) + ", " + note;
  if (drawing_) {
    std::fprintf(stream_, "\r%s   %s", text.c_str(), finished ? "\n" : "");
  } else {
    std::fprintf(stream_, "%s\n", text.c_str());
  }
  std::fflush(stream_);
}

}  // namespace deep_ois
