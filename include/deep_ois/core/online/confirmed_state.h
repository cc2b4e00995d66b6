// The confirm-then-persist rule for anything learned online (the stabiliser model today; an
// online calibration is the second kind, in its own file next to the model):
//
//  - A new state is first a *trial*: it is put in use at once, and nothing is written.
//  - The per-pair check then scores, on the same tracks of each usable pair after the swap, the
//    trial, the state it replaced and the plain gyro (mean track error, pixels; TrialEvidence).
//  - Once `ConfirmationOptions::pairs` usable pairs are in, the verdict:
//      worse than the state it replaced   -> undone: the replaced state is in use again, nothing
//                                            is written;
//      else worse than the plain gyro     -> kept in use but not confirmed: nothing is written
//                                            (the file keeps the last confirmed state, which was
//                                            never worse than the plain gyro where it was checked);
//      else                               -> confirmed, and only then persisted (atomically:
//                                            atomic_file_write.h).
//    "Worse" is a mean above the other's by more than a fraction and some pixels; by default
//    stricter than the fallback's margins (5 % and 0.02 px), as what is written must never be
//    worse than the plain gyro: 0 % and 0.01 px. The three figures are on the same tracks, so
//    their differences are not blurred by which tracks a pair happened to have.
//  - The persisted state is therefore always the last confirmed one, never the last tried; a kill
//    during the write leaves the previous confirmed file.
//
// Pairs the caller does not count (replayed data already learned from, unusable pairs) never reach
// addPair. Not thread-safe: the owner serialises the calls (the persist function runs inside
// addPair, on the caller's thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>

namespace deep_ois {

struct ConfirmationOptions {
  // Usable pairs checked with the trial before its verdict. On the shared VideoIMUCapture recording
  // (issue 33) a swap worse than the plain gyro over 103 pairs looked better on its first 40: 60.
  std::size_t pairs = 60;
  double worse_fraction = 0.0;  // worse: a mean residual above the other's by this fraction...
  double margin_px = 0.01;      // ...and by more than this many pixels
  std::string validate() const;
};

enum class TrialVerdict {
  kPending,          // not enough pairs yet (or no trial)
  kConfirmed,        // not worse than the replaced state nor the plain gyro: persisted
  kUndone,           // worse than the state it replaced: that one is back in use
  kKeptUnconfirmed,  // not worse than the replaced state but worse than the plain gyro: not persisted
};

const char* toString(TrialVerdict verdict);

// The per-pair check's figures on one trial: mean track errors on the same tracks, pixels.
class TrialEvidence {
 public:
  void add(double trial_px, double replaced_px, double gyro_px);
  std::size_t pairs() const { return pairs_; }
  double trialMeanPx() const;
  double replacedMeanPx() const;
  double gyroMeanPx() const;
  // kPending below options.pairs, else the verdict of the rule above.
  TrialVerdict verdict(const ConfirmationOptions& options) const;
  // "1.250 px with it, 1.130 px with the one it replaced, 1.130 px with the plain gyro, on 118 pairs"
  std::string summary() const;

 private:
  std::size_t pairs_ = 0;
  double trial_sum_ = 0.0, replaced_sum_ = 0.0, gyro_sum_ = 0.0;
};

// One kind of state learned online, per camera. `State` is copyable (e.g. a shared_ptr to const).
template <typename State>
class ConfirmedState {
 public:
  // Writes the state (atomically; throws on failure). Called only with a confirmed state.
  using Persist = std::function<void(const State&)>;

  struct Outcome {
    TrialVerdict verdict = TrialVerdict::kPending;
    std::string persist_error;  // the write failed (the state stays confirmed in memory)
  };

  // `start` is in use and counts as confirmed (it is what the file holds, or the shipped default):
  // nothing is written for it.
  ConfirmedState(State start, Persist persist, ConfirmationOptions options = {})
      : in_use_(start), replaced_(start), confirmed_(std::move(start)), persist_(std::move(persist)),
        options_(options) {}

  const State& inUse() const { return in_use_; }
  const State& confirmed() const { return confirmed_; }  // what was last persisted (or the start)
  const State& replaced() const { return replaced_; }    // in use before the trial (on trial only)
  bool onTrial() const { return on_trial_; }
  std::uint64_t trialId() const { return trial_id_; }  // +1 per trial started
  const TrialEvidence& evidence() const { return evidence_; }
  const ConfirmationOptions& options() const { return options_; }

  // Puts `trial` in use on probation; nothing is written. A trial already on probation is replaced
  // (the state before it stays the one to restore).
  void startTrial(State trial) {
    if (!on_trial_) replaced_ = in_use_;
    in_use_ = std::move(trial);
    on_trial_ = true;
    evidence_ = TrialEvidence();
    ++trial_id_;
  }

  // One usable pair checked after the swap, mean track errors on the same tracks (pixels): with the
  // trial, with the state it replaced, with the plain gyro. Ends the trial once enough pairs are in.
  Outcome addPair(double trial_px, double replaced_px, double gyro_px) {
    Outcome outcome;
    if (!on_trial_) return outcome;
    evidence_.add(trial_px, replaced_px, gyro_px);
    outcome.verdict = evidence_.verdict(options_);
    switch (outcome.verdict) {
      case TrialVerdict::kPending:
        break;
      case TrialVerdict::kUndone:
        undo();
        break;
      case TrialVerdict::kKeptUnconfirmed:
        on_trial_ = false;
        break;
      case TrialVerdict::kConfirmed:
        on_trial_ = false;
        confirmed_ = in_use_;
        try {
          if (persist_) persist_(confirmed_);
        } catch (const std::exception& e) {
          outcome.persist_error = e.what();
        }
        break;
    }
    return outcome;
  }

  // Ends the trial by other evidence (e.g. the lens motions after the swap): the state it replaced
  // is in use again; nothing is written.
  void undo() {
    if (!on_trial_) return;
    in_use_ = replaced_;
    on_trial_ = false;
  }

 private:
  State in_use_, replaced_, confirmed_;
  Persist persist_;
  ConfirmationOptions options_;
  bool on_trial_ = false;
  std::uint64_t trial_id_ = 0;
  TrialEvidence evidence_;
};

}  // namespace deep_ois
