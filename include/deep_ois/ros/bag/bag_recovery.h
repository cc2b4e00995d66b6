// Reads what is readable of a rosbag whose index is missing or damaged: a recording cut short
// (copied while written, disk full) or a bag whose writer was killed (SIGKILL, power loss) before
// it wrote its index. rosbag's C++ API refuses such a file ("cannot open the bag"); `rosbag
// reindex` repairs it in place. This scans the file's chunks from the start, as reindex does,
// and keeps every message up to the first damaged or incomplete record.
//
// Rosbag format 2.0: "#ROSBAG V2.0\n", then records <u32 header length><header><u32 data
// length><data>; header fields <u32 length>"name=value". Chunk records (op 0x05) hold connection
// (op 0x07) and message (op 0x02) records, compressed by "none", "bz2" or "lz4". A writer that
// dies inside a chunk leaves that chunk's size fields at 0: for an uncompressed chunk its complete
// messages are still read; a compressed one is lost from its start.
#pragma once

#include <cstdint>
#include <string>

namespace deep_ois {

struct BagRecoveryReport {
  std::size_t chunks = 0;          // chunks (complete or not) messages were read from
  std::size_t messages = 0;        // messages kept
  std::uint64_t bytes_read = 0;    // the file up to the end of the last record kept
  std::uint64_t file_bytes = 0;
  std::string stopped_because;     // why reading stopped before the end; empty when it did not

  // One sentence: what was kept and what was lost.
  std::string text() const;
};

// Writes every message of `damaged` before the damage to `repaired`, a new indexed, uncompressed
// bag with the same topics, types and connection headers. Throws std::runtime_error naming the
// file when `damaged` is not a rosbag 2.0 file or `repaired` cannot be written.
BagRecoveryReport recoverBag(const std::string& damaged, const std::string& repaired);

// The file to read a bag from: the bag itself when rosbag opens it, otherwise a repaired copy in
// the temporary directory (deleted with this object). Readers open path() with rosbag as usual.
class ReadableBag {
 public:
  // Throws std::runtime_error naming `path` when the bag opens neither way (missing, not a bag).
  explicit ReadableBag(const std::string& path);
  ~ReadableBag();
  ReadableBag(const ReadableBag&) = delete;
  ReadableBag& operator=(const ReadableBag&) = delete;

  const std::string& path() const { return read_path_; }
  const std::string& originalPath() const { return original_path_; }
  bool recovered() const { return read_path_ != original_path_; }
  const BagRecoveryReport& recovery() const { return report_; }
  // Empty for an intact bag; otherwise "<path>: <why it did not open>; <report.text()>".
  const std::string& note() const { return note_; }
  // `text` with the repaired copy's path replaced by the original's (for error messages).
  std::string originalNames(std::string text) const;

 private:
  std::string original_path_;
  std::string read_path_;
  BagRecoveryReport report_;
  std::string note_;
};

}  // namespace deep_ois
