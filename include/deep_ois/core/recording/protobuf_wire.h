// A minimal reader of the protobuf wire format (varint, 64-bit, length-delimited, 32-bit fields),
// enough to read a logger's metadata file without generated code. Why hand-written rather than
// libprotobuf + protoc: the loggers' .proto files are not shipped with the recordings (only field
// numbers, recording_schema.txt), a file is read once, field by field, into plain structs, and an
// error can then name the file, the message (e.g. "imu[812]") and the byte offset where it broke,
// which a generated ParseFromString() does not. Pure core: no ROS.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace deep_ois {

// One field of a message. `bytes` (length-delimited) points into the reader's buffer.
struct ProtobufField {
  int number = 0;
  int wire_type = 0;         // 0 varint, 1 64-bit, 2 length-delimited, 5 32-bit
  std::uint64_t value = 0;   // varint, or the raw bits of a 64/32-bit field
  const std::uint8_t* bytes = nullptr;
  std::size_t size = 0;      // of `bytes`
  std::size_t offset = 0;    // byte offset of the field's key in the file
};

// Reads the fields of one message, in order. Every error throws RecordingFormatError naming the
// file, the message path and the byte offset.
class ProtobufMessageReader {
 public:
  // `data`/`size`: the message's bytes; `file_offset`: where they start in `file`; `path`: the
  // message's name for errors ("VideoCaptureData.imu[12]").
  ProtobufMessageReader(const std::uint8_t* data, std::size_t size, std::size_t file_offset, std::string file,
                        std::string path);

  bool next(ProtobufField& field);  // false at the end of the message

  // Sub-message reader of a length-delimited field.
  ProtobufMessageReader child(const ProtobufField& field, const std::string& name) const;

  // Typed views of a field (each checks the wire type and throws naming the field otherwise).
  std::int64_t int64(const ProtobufField& field, const char* name) const;
  bool boolean(const ProtobufField& field, const char* name) const;
  float float32(const ProtobufField& field, const char* name) const;
  std::string string(const ProtobufField& field) const;
  // A packed repeated float (or a single unpacked one, appended).
  void appendFloats(const ProtobufField& field, const char* name, std::vector<float>& out) const;

  [[noreturn]] void fail(std::size_t file_offset, const std::string& problem) const;
  const std::string& path() const { return path_; }

 private:
  std::uint64_t varint(std::size_t& pos) const;
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::size_t file_offset_;
  std::string file_;
  std::string path_;
};

// The whole file's bytes. Throws RecordingFormatError when it cannot be read.
std::vector<std::uint8_t> readBinaryFile(const std::string& path);

}  // namespace deep_ois
