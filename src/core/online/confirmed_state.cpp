#include "deep_ois/core/online/confirmed_state.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

namespace deep_ois {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

std::string ConfirmationOptions::validate() const {
  std::ostringstream why;
  if (pairs < 1) why << "confirmation pairs must be at least 1";
  else if (!(worse_fraction >= 0.0)) why << "confirmation worse_fraction must not be negative (got " << worse_fraction << ")";
  else if (!(margin_px >= 0.0)) why << "confirmation margin_px must not be negative (got " << margin_px << ")";
  return why.str();
}

const char* toString(TrialVerdict verdict) {
  switch (verdict) {
    case TrialVerdict::kPending: return "pending";
    case TrialVerdict::kConfirmed: return "confirmed";
    case TrialVerdict::kUndone: return "undone";
    case TrialVerdict::kKeptUnconfirmed: return "kept, not confirmed";
  }
  return "unknown";
}

void TrialEvidence::add(double trial_px, double replaced_px, double gyro_px) {
  ++pairs_;
  trial_sum_ += trial_px;
  replaced_sum_ += replaced_px;
  gyro_sum_ += gyro_px;
}

double TrialEvidence::trialMeanPx() const { return pairs_ ? trial_sum_ / pairs_ : kNaN; }
double TrialEvidence::replacedMeanPx() const { return pairs_ ? replaced_sum_ / pairs_ : kNaN; }
double TrialEvidence::gyroMeanPx() const { return pairs_ ? gyro_sum_ / pairs_ : kNaN; }

TrialVerdict TrialEvidence::verdict(const ConfirmationOptions& options) const {
  if (pairs_ < options.pairs) return TrialVerdict::kPending;
  const auto worse = [&](double a, double b) { return a > b * (1.0 + options.worse_fraction) + options.margin_px; };
  // A NaN figure (a caller's bug) is never a confirmation.
  // A figure that is not finite (a caller's bug) is never a confirmation.
  if (!std::isfinite(trialMeanPx()) || !std::isfinite(replacedMeanPx()) || !std::isfinite(gyroMeanPx()))
    return TrialVerdict::kUndone;
  if (worse(trialMeanPx(), replacedMeanPx())) return TrialVerdict::kUndone;
  if (worse(trialMeanPx(), gyroMeanPx())) return TrialVerdict::kKeptUnconfirmed;
  return TrialVerdict::kConfirmed;
}

std::string TrialEvidence::summary() const {
  char text[200];
  std::snprintf(text, sizeof text,
                "%.3f px with it, %.3f px with the one it replaced, %.3f px with the plain gyro, on %zu pairs",
                trialMeanPx(), replacedMeanPx(), gyroMeanPx(), pairs_);
  return text;
}

}  // namespace deep_ois
