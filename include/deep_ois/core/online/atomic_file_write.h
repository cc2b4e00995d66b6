// Writing a file so that a reader, or a process killed at any moment of the write, sees either the
// old complete file or the new complete one, never a part: the text goes to a file beside the
// target (`<path>.partial.<pid>`), is flushed to the disk (fsync), and is renamed over the target;
// the folder is synced too so that the rename survives a power cut. What the online learner keeps
// per camera is written this way (confirmed_state.h). Pure C++ (POSIX): no ROS.
#pragma once

#include <stdexcept>
#include <string>

namespace deep_ois {

struct AtomicWriteOptions {
  // Test hook, seconds: after the first half of the text is written to the partial file, the writer
  // pauses this long before the rest, the sync and the rename, so that a test can kill the process
  // during a write (~learning_test_write_pause). 0 in normal use.
  double test_pause_s = 0.0;
};

struct AtomicWriteError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The partial file a write of `path` by this process goes through.
std::string partialPathOf(const std::string& path);

// Writes `text` to `path` atomically. Throws AtomicWriteError naming the file and the system's
// reason (a missing or unwritable folder, a full disk); the target is then unchanged and the
// partial file removed.
void writeFileAtomically(const std::string& path, const std::string& text, const AtomicWriteOptions& options = {});

// Removes the partial files beside `path` left by processes that no longer run (killed during a
// write); returns how many. A partial file of a running process is left alone.
int removeStalePartialFiles(const std::string& path);

}  // namespace deep_ois
