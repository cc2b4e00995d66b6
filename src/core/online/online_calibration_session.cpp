#include "deep_ois/core/online/online_calibration_session.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace deep_ois {
namespace {

// A pair scored for a trial needs this many tracks that either calibration explains.
constexpr int kMinTrialTracks = 10;

bool sameCalibration(const CameraImuCalibration& a, const CameraImuCalibration& b) {
  return a.time_offset_s == b.time_offset_s && a.readout_time_s == b.readout_time_s &&
         a.gyro_bias_rad_s == b.gyro_bias_rad_s && a.imu_to_camera_rotation == b.imu_to_camera_rotation;
}

// The shift at `row` (pixels) from the per-patch shifts at the patches' capture rows.
Eigen::Vector2d shiftAtRow(const std::vector<Eigen::Vector2d>& shifts, double row, int height, double fraction) {
  const int n = static_cast<int>(shifts.size());
  const double position = row * n / std::max(1, height) - fraction;  // in patches, 0 = patch 0's capture row
  if (position <= 0.0) return shifts.front();
  if (position >= n - 1) return shifts.back();
  const int i = static_cast<int>(std::floor(position));
  const double w = position - i;
  return (1.0 - w) * shifts[static_cast<std::size_t>(i)] + w * shifts[static_cast<std::size_t>(i + 1)];
}

std::string millis(double seconds) {
  char text[40];
  std::snprintf(text, sizeof text, "%.3f ms", 1e3 * seconds);
  return text;
}

}  // namespace

std::vector<FeatureMatch> removeLensShift(const OnlineFramePair& pair, const PairLensShift& lens) {
  if (lens.shift_a_px.empty() || lens.shift_a_px.size() != lens.shift_b_px.size()) return pair.matches;
  const CameraModel& camera = pair.camera;
  const double fraction = pair.timing.patch_time == PatchTimeReference::kPatchCentre ? 0.5 : 0.0;
  std::vector<Eigen::Vector2d> a, b;
  a.reserve(pair.matches.size());
  b.reserve(pair.matches.size());
  for (const FeatureMatch& m : pair.matches) {
    a.emplace_back(m.point_a_px.x, m.point_a_px.y);
    b.emplace_back(m.point_b_px.x, m.point_b_px.y);
  }
  // The shift moves undistorted pixels (K(s) = K with the principal point moved by s).
  if (camera.hasDistortion()) {
    camera.undistortPoints(a);
    camera.undistortPoints(b);
  }
  for (std::size_t k = 0; k < a.size(); ++k) {
    a[k] -= shiftAtRow(lens.shift_a_px, pair.matches[k].point_a_px.y, camera.height(), fraction);
    b[k] -= shiftAtRow(lens.shift_b_px, pair.matches[k].point_b_px.y, camera.height(), fraction);
  }
  if (camera.hasDistortion()) {
    camera.distortPoints(a);
    camera.distortPoints(b);
  }
  std::vector<FeatureMatch> out = pair.matches;
  for (std::size_t k = 0; k < out.size(); ++k) {
    out[k].point_a_px = cv::Point2f(static_cast<float>(a[k].x()), static_cast<float>(a[k].y()));
    out[k].point_b_px = cv::Point2f(static_cast<float>(b[k].x()), static_cast<float>(b[k].y()));
  }
  return out;
}

OnlineFramePair lenslessPair(const OnlineFramePair& pair, const PairLensShift* lens) {
  OnlineFramePair lensless;
  lensless.stamp_a_s = pair.stamp_a_s;
  lensless.stamp_b_s = pair.stamp_b_s;
  lensless.timing = pair.timing;
  lensless.camera = pair.camera;
  lensless.rates = pair.rates;
  lensless.tracked = pair.tracked;
  if (pair.tracked) lensless.matches = lens ? removeLensShift(pair, *lens) : pair.matches;
  return lensless;
}

OnlineCalibrationSession::OnlineCalibrationSession(const OnlineCalibrationOptions& options, std::size_t confirm_pairs,
                                                   const CameraModel& camera, const CameraImuCalibration& start,
                                                   ConfirmedState<CameraImuCalibration>::Persist persist,
                                                   std::string persisted_to)
    : estimator_(options, camera, start),
      feed_(DelayedCalibrationFeed::coverageFor(options)),
      trials_(start, std::move(persist),
              [confirm_pairs] {
                ConfirmationOptions confirmation;
                confirmation.pairs = confirm_pairs;
                return confirmation;
              }()),
      confirm_pairs_(confirm_pairs),
      persisted_to_(std::move(persisted_to)),
      session_start_(start) {}

void OnlineCalibrationSession::restartTimeline() {
  estimator_.restartTimeline();
  feed_.clear();
}

OnlineCalibrationSession::Outcome OnlineCalibrationSession::addPair(const OnlineFramePair& lensless) {
  Outcome outcome;
  // The pairs reach the estimator once the gyro covers them (a few pairs later).
  bool changed_in_use = false;
  const std::vector<OnlineCalibrationPair> added = feed_.feed(lensless, estimator_, &changed_in_use);
  const OnlineCalibrationStatus& status = estimator_.status();
  const std::uint32_t version_before = applied_version_;
  if (status.version != estimator_version_) {
    // Confidently better on the held-out pairs: applied now, on trial from the next pair.
    // The estimator's version before the first swap of this trial: an undo rewinds it to before
    // that swap (a trial replaced by a later one restores what was in use before the first).
    if (!trials_.onTrial()) trial_first_version_ = estimator_version_ + 1;
    estimator_version_ = status.version;
    trials_.startTrial(status.in_use);
    ++applied_version_;
    std::ostringstream said;
    said << "online calibration applied (version " << applied_version_ << "): time offset "
         << millis(status.in_use.time_offset_s) << " +- " << millis(status.in_use.time_offset_sigma_s)
         << (status.in_use.time_offset_rate != 0.0
                 ? " drifting " + std::to_string(1e6 * status.in_use.time_offset_rate) + " us/s"
                 : std::string())
         << ", readout " << millis(status.in_use.readout_time_s) << " +- "
         << millis(status.in_use.readout_time_sigma_s) << "; " << status.last_reason
         << "; on trial until the per-pair check confirms it on " << confirm_pairs_ << " pairs";
    outcome.log = said.str();
  } else if (trials_.onTrial()) {
    for (const OnlineCalibrationPair& added_pair : added) {
      if (added_pair.matches.empty()) continue;
      judgeTrial(added_pair);
      if (!trials_.onTrial()) break;
    }
    if (applied_version_ != version_before || !trials_.onTrial()) {
      const TrialEvidence& e = trials_.evidence();
      char text[240];
      std::snprintf(text, sizeof text, "%.3f px with it, %.3f px with the one it replaced, %.3f px with the start, on %zu pairs",
                    e.trialMeanPx(), e.replacedMeanPx(), e.gyroMeanPx(), e.pairs());
      outcome.log = "online calibration " + std::string(applied_version_ != version_before ? "undone (worse than the one it "
                                                                                              "replaced): "
                                                                                            : "trial ended: ") +
                    text;
    }
  }
  if (trials_.onTrial()) {
    const TrialEvidence& e = trials_.evidence();
    char text[240];
    std::snprintf(text, sizeof text, "on trial: %zu of %zu pairs (%.3f px with it, %.3f px with the one it replaced)",
                  e.pairs(), confirm_pairs_, e.trialMeanPx(), e.replacedMeanPx());
    outcome.confirmation = e.pairs() ? text : "on trial: waiting for usable pairs";
  } else {
    outcome.confirmation = confirmation_;
  }
  return outcome;
}

void OnlineCalibrationSession::judgeTrial(const OnlineCalibrationPair& scored) {
  const std::vector<OnlineCalibrationPair> pairs{scored};
  double trial_px = NAN, replaced_px = NAN, start_px = NAN;
  int tracks = 0;
  estimator_.scorePair(pairs, trials_.inUse(), trials_.replaced(), &trial_px, &replaced_px, &tracks);
  if (tracks < kMinTrialTracks || !std::isfinite(trial_px) || !std::isfinite(replaced_px)) return;
  start_px = replaced_px;
  if (!sameCalibration(session_start_, trials_.replaced())) {
    double trial_again_px = NAN;
    int start_tracks = 0;
    estimator_.scorePair(pairs, trials_.inUse(), session_start_, &trial_again_px, &start_px, &start_tracks);
    // Scored on the tracks either explains: the start's figure is taken relative to the trial's there.
    if (start_tracks >= kMinTrialTracks && std::isfinite(start_px) && std::isfinite(trial_again_px))
      start_px += trial_px - trial_again_px;
    else
      start_px = replaced_px;
  }
  const auto outcome = trials_.addPair(trial_px, replaced_px, start_px);
  switch (outcome.verdict) {
    case TrialVerdict::kUndone:
      ++applied_version_;  // the replaced calibration is applied again
      ++swaps_undone_;
      // The estimator returns to its state before the undone swap's fit, so that it does not offer
      // the same calibration again from the filters that produced it.
      estimator_.rewindBeforeSwap(trial_first_version_);
      confirmation_ = "undone: worse than the calibration it replaced (" + trials_.evidence().summary() + ")";
      break;
    case TrialVerdict::kConfirmed:
      ++swaps_confirmed_;
      confirmation_ = outcome.persist_error.empty()
                          ? "confirmed and written to " + persisted_to_ + " (" + trials_.evidence().summary() + ")"
                          : "confirmed, but the write failed: " + outcome.persist_error;
      if (!outcome.persist_error.empty()) ++saves_failed_;
      break;
    case TrialVerdict::kKeptUnconfirmed:
      confirmation_ = "kept in use, not written: worse than the start (" + trials_.evidence().summary() + ")";
      break;
    case TrialVerdict::kPending:
      break;
  }
}

}  // namespace deep_ois
