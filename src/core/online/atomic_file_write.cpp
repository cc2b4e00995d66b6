#include "deep_ois/core/online/atomic_file_write.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

std::string systemReason(int error) { return std::strerror(error); }

// Writes all of `size` bytes (write() may write fewer).
bool writeAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

std::string partialPathOf(const std::string& path) { return path + ".partial." + std::to_string(::getpid()); }

void writeFileAtomically(const std::string& path, const std::string& text, const AtomicWriteOptions& options) {
  const std::string partial = partialPathOf(path);
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int error = errno;
    fs::path folder = fs::path(path).parent_path();
    throw AtomicWriteError(path + ": cannot create " + partial + " beside it (" + systemReason(error) +
                           (folder.empty() || fs::is_directory(folder) ? ")" : "; the folder does not exist)"));
  }
  const auto fail = [&](const std::string& what) {
    const int error = errno;
    ::close(fd);
    std::remove(partial.c_str());
    throw AtomicWriteError(path + ": " + what + " (" + systemReason(error) + "); the file is unchanged");
  };
  const std::size_t half = options.test_pause_s > 0.0 ? text.size() / 2 : text.size();
  if (!writeAll(fd, text.data(), half)) fail("writing failed");
  if (options.test_pause_s > 0.0) {
    std::this_thread::sleep_for(std::chrono::duration<double>(options.test_pause_s));
    if (!writeAll(fd, text.data() + half, text.size() - half)) fail("writing failed");
  }
  // On the disk before the rename: otherwise a power cut after it may leave an empty file.
  if (::fsync(fd) != 0) fail("syncing to the disk failed");
  if (::close(fd) != 0) {
    const int error = errno;
    std::remove(partial.c_str());
    throw AtomicWriteError(path + ": closing failed (" + systemReason(error) + "); the file is unchanged");
  }
  if (std::rename(partial.c_str(), path.c_str()) != 0) {
    const int error = errno;
    std::remove(partial.c_str());
    throw AtomicWriteError(path + ": cannot replace it (rename failed: " + systemReason(error) +
                           "); the file is unchanged");
  }
  // The rename itself on the disk (best effort: a folder that cannot be opened is no error here).
  fs::path folder = fs::path(path).parent_path();
  if (folder.empty()) folder = ".";
  const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

int removeStalePartialFiles(const std::string& path) {
  const fs::path target(path);
  fs::path folder = target.parent_path();
  if (folder.empty()) folder = ".";
  const std::string prefix = target.filename().string() + ".partial.";
  int removed = 0;
  std::error_code error;
  for (fs::directory_iterator it(folder, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string pid_text = name.substr(prefix.size());
    if (pid_text.empty() || pid_text.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
    // Alive (or not ours to signal): left alone.
    if (pid == ::getpid() || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    if (fs::remove(it->path(), ignored)) ++removed;
  }
  return removed;
}

}  // namespace deep_ois
