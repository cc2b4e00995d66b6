// The confirm-then-persist rule (core/online/confirmed_state.h) and the atomic write under it
// (core/online/atomic_file_write.h): a trial writes nothing until the per-pair check confirms it; a
// trial worse than the state it replaced is undone and never written; a trial worse than the plain
// gyro is not written; a kill during a write leaves the last confirmed file.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "deep_ois/core/online/atomic_file_write.h"
#include "deep_ois/core/online/confirmed_state.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

// The state is a string; "writing" it appends to a list, so that a test sees every write.
struct Recorder {
  std::vector<std::string> written;
  ConfirmedState<std::string>::Persist persist() {
    return [this](const std::string& s) { written.push_back(s); };
  }
};

ConfirmationOptions threePairs() {
  ConfirmationOptions o;
  o.pairs = 3;
  return o;
}

TEST(ConfirmedState, ATrialWritesNothingUntilConfirmedThenWritesIt) {
  Recorder recorder;
  ConfirmedState<std::string> state("start", recorder.persist(), threePairs());
  EXPECT_FALSE(state.onTrial());
  state.startTrial("trial");
  EXPECT_EQ(state.inUse(), "trial");  // in use at once
  EXPECT_EQ(state.confirmed(), "start");
  EXPECT_EQ(state.addPair(0.50, 0.80, 0.80).verdict, TrialVerdict::kPending);
  EXPECT_EQ(state.addPair(0.50, 0.80, 0.80).verdict, TrialVerdict::kPending);
  EXPECT_TRUE(recorder.written.empty()) << "written before its confirmation";
  EXPECT_EQ(state.addPair(0.50, 0.80, 0.80).verdict, TrialVerdict::kConfirmed);
  ASSERT_EQ(recorder.written, std::vector<std::string>{"trial"});
  EXPECT_EQ(state.confirmed(), "trial");
  EXPECT_FALSE(state.onTrial());
  // After the verdict, pairs change nothing.
  EXPECT_EQ(state.addPair(5.0, 0.1, 0.1).verdict, TrialVerdict::kPending);
  EXPECT_EQ(recorder.written.size(), 1u);
}

// The double-replay case in figures: the trial's mean 1.25 px against 1.13 px for the
// model it replaced ("no lens motion", the plain gyro).
TEST(ConfirmedState, ATrialWorseThanWhatItReplacedIsUndoneAndNeverWritten) {
  Recorder recorder;
  ConfirmedState<std::string> state("no lens motion", recorder.persist(), threePairs());
  state.startTrial("excursion_rate_v1");
  for (int k = 0; k < 2; ++k) EXPECT_EQ(state.addPair(1.25, 1.13, 1.13).verdict, TrialVerdict::kPending);
  const auto outcome = state.addPair(1.25, 1.13, 1.13);
  EXPECT_EQ(outcome.verdict, TrialVerdict::kUndone);
  EXPECT_EQ(state.inUse(), "no lens motion");
  EXPECT_EQ(state.confirmed(), "no lens motion");
  EXPECT_TRUE(recorder.written.empty());
  EXPECT_NE(state.evidence().summary().find("1.250 px with it, 1.130 px with the one it replaced"),
            std::string::npos)
      << state.evidence().summary();
}

TEST(ConfirmedState, WithinTheMarginsIsNotWorse) {
  Recorder recorder;
  ConfirmedState<std::string> state("a", recorder.persist(), threePairs());
  state.startTrial("b");
  // 1.0 + 0.01 px: 1.009 is not worse (and 1.02 is: the next test).
  for (int k = 0; k < 3; ++k) state.addPair(1.009, 1.0, 1.0);
  EXPECT_EQ(recorder.written, std::vector<std::string>{"b"});
  state.startTrial("c");
  for (int k = 0; k < 3; ++k) state.addPair(1.02, 1.0, 1.0);
  EXPECT_EQ(state.inUse(), "b");
}

TEST(ConfirmedState, BetterThanWhatItReplacedButWorseThanTheGyroIsKeptButNotWritten) {
  Recorder recorder;
  ConfirmedState<std::string> state("bad start", recorder.persist(), threePairs());
  state.startTrial("less bad");
  for (int k = 0; k < 3; ++k) state.addPair(0.9, 1.2, 0.5);
  EXPECT_FALSE(state.onTrial());
  EXPECT_EQ(state.inUse(), "less bad");
  EXPECT_EQ(state.confirmed(), "bad start");
  EXPECT_TRUE(recorder.written.empty());
  // The next trial is judged against the one in use, and restores it when worse.
  state.startTrial("worse");
  for (int k = 0; k < 3; ++k) state.addPair(2.0, 0.9, 0.5);
  EXPECT_EQ(state.inUse(), "less bad");
  EXPECT_TRUE(recorder.written.empty());
}

TEST(ConfirmedState, UndoByOtherEvidenceRestoresWithoutWriting) {
  Recorder recorder;
  ConfirmedState<std::string> state("a", recorder.persist(), threePairs());
  state.startTrial("b");
  state.addPair(0.1, 0.2, 0.2);
  state.undo();
  EXPECT_EQ(state.inUse(), "a");
  EXPECT_FALSE(state.onTrial());
  EXPECT_EQ(state.addPair(0.1, 0.2, 0.2).verdict, TrialVerdict::kPending);
  EXPECT_TRUE(recorder.written.empty());
  // A second trial started while one is on trial keeps the state to restore.
  state.startTrial("c");
  state.startTrial("d");
  EXPECT_EQ(state.replaced(), "a");
  EXPECT_EQ(state.trialId(), 3u);
  for (int k = 0; k < 3; ++k) state.addPair(0.9, 0.2, 0.2);
  EXPECT_EQ(state.inUse(), "a");
}

TEST(ConfirmedState, AFailedWriteIsReportedAndTheStateStaysConfirmed) {
  ConfirmedState<std::string> state("a", [](const std::string&) { throw std::runtime_error("disk full"); },
                                    threePairs());
  state.startTrial("b");
  state.addPair(0.1, 0.2, 0.2);
  state.addPair(0.1, 0.2, 0.2);
  const auto outcome = state.addPair(0.1, 0.2, 0.2);
  EXPECT_EQ(outcome.verdict, TrialVerdict::kConfirmed);
  EXPECT_EQ(outcome.persist_error, "disk full");
  EXPECT_EQ(state.confirmed(), "b");
}

TEST(ConfirmedState, NonFiniteFiguresAreNeverAConfirmation) {
  Recorder recorder;
  ConfirmedState<std::string> state("a", recorder.persist(), threePairs());
  state.startTrial("b");
  for (int k = 0; k < 3; ++k) state.addPair(0.1, std::nan(""), 0.2);
  EXPECT_EQ(state.inUse(), "a");
  EXPECT_TRUE(recorder.written.empty());
}

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(AtomicFileWrite, WritesAndReplaces) {
  const fs::path dir = fs::temp_directory_path() / ("deep_ois_atomic_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "state.yaml").string();
  writeFileAtomically(path, "first\n");
  writeFileAtomically(path, "second\n");
  EXPECT_EQ(readAll(path), "second\n");
  EXPECT_FALSE(fs::exists(partialPathOf(path)));
  EXPECT_THROW(writeFileAtomically((dir / "missing" / "x.yaml").string(), "x"), AtomicWriteError);
  fs::remove_all(dir);
}

// A process killed (SIGKILL) in the middle of a write (the test hook pauses it after half the
// text) leaves the last complete file, and a partial file that the next start removes.
TEST(AtomicFileWrite, AKillDuringTheWriteKeepsTheLastFile) {
  const fs::path dir = fs::temp_directory_path() / ("deep_ois_atomic_kill_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "state.yaml").string();
  writeFileAtomically(path, "confirmed: 1\n");
  const std::string next(100000, 'x');
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    AtomicWriteOptions slow;
    slow.test_pause_s = 30.0;
    try {
      writeFileAtomically(path, next, slow);
    } catch (...) {
    }
    ::_exit(0);
  }
  const std::string partial = path + ".partial." + std::to_string(child);
  bool seen = false;
  for (int k = 0; k < 500 && !seen; ++k) {
    std::error_code ignored;
    seen = fs::exists(partial, ignored) && fs::file_size(partial, ignored) >= next.size() / 2;
    if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(seen) << "the child never started its write";
  EXPECT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(readAll(path), "confirmed: 1\n");
  EXPECT_TRUE(fs::exists(partial));
  EXPECT_EQ(removeStalePartialFiles(path), 1);
  EXPECT_FALSE(fs::exists(partial));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace deep_ois
