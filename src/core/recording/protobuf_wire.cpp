#include "deep_ois/core/recording/protobuf_wire.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>

#include "deep_ois/core/recording/phone_recording.h"

namespace deep_ois {

ProtobufMessageReader::ProtobufMessageReader(const std::uint8_t* data, std::size_t size, std::size_t file_offset,
                                             std::string file, std::string path)
    : data_(data), size_(size), file_offset_(file_offset), file_(std::move(file)), path_(std::move(path)) {}

void ProtobufMessageReader::fail(std::size_t file_offset, const std::string& problem) const {
  throw RecordingFormatError(file_, 0, path_ + " at byte " + std::to_string(file_offset) + ": " + problem);
}

std::uint64_t ProtobufMessageReader::varint(std::size_t& pos) const {
  std::uint64_t value = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= size_) fail(file_offset_ + pos, "truncated (the file ends inside a number)");
    const std::uint8_t byte = data_[pos++];
    value |= static_cast<std::uint64_t>(byte & 0x7f) << shift;
    if (!(byte & 0x80)) return value;
  }
  fail(file_offset_ + pos, "a number longer than 10 bytes (not protobuf)");
}

bool ProtobufMessageReader::next(ProtobufField& field) {
  if (pos_ >= size_) return false;
  field = ProtobufField{};
  field.offset = file_offset_ + pos_;
  const std::uint64_t key = varint(pos_);
  field.number = static_cast<int>(key >> 3);
  field.wire_type = static_cast<int>(key & 7);
  if (field.number == 0) fail(field.offset, "field number 0 (not protobuf, or a truncated file)");
  auto need = [&](std::size_t n) {
    if (size_ - pos_ < n) {
      fail(field.offset, "truncated: field " + std::to_string(field.number) + " needs " + std::to_string(n) +
                             " bytes, " + std::to_string(size_ - pos_) + " are left");
    }
  };
  switch (field.wire_type) {
    case 0:
      field.value = varint(pos_);
      break;
    case 1:
      need(8);
      std::memcpy(&field.value, data_ + pos_, 8);  // little-endian hosts (x86, ARM)
      pos_ += 8;
      break;
    case 5: {
      need(4);
      std::uint32_t bits = 0;
      std::memcpy(&bits, data_ + pos_, 4);
      field.value = bits;
      pos_ += 4;
      break;
    }
    case 2: {
      const std::uint64_t length = varint(pos_);
      need(static_cast<std::size_t>(std::min<std::uint64_t>(length, size_ + 1)));
      field.bytes = data_ + pos_;
      field.size = static_cast<std::size_t>(length);
      pos_ += field.size;
      break;
    }
    default:
      fail(field.offset, "wire type " + std::to_string(field.wire_type) + " of field " +
                             std::to_string(field.number) + " (not protobuf, or a truncated file)");
  }
  return true;
}

ProtobufMessageReader ProtobufMessageReader::child(const ProtobufField& field, const std::string& name) const {
  if (field.wire_type != 2) fail(field.offset, name + " is not a message (wire type " + std::to_string(field.wire_type) + ")");
  return ProtobufMessageReader(field.bytes, field.size, static_cast<std::size_t>(field.bytes - data_) + file_offset_,
                               file_, path_ + "." + name);
}

std::int64_t ProtobufMessageReader::int64(const ProtobufField& field, const char* name) const {
  if (field.wire_type != 0) fail(field.offset, std::string(name) + " is not an integer");
  return static_cast<std::int64_t>(field.value);
}

bool ProtobufMessageReader::boolean(const ProtobufField& field, const char* name) const {
  return int64(field, name) != 0;
}

float ProtobufMessageReader::float32(const ProtobufField& field, const char* name) const {
  if (field.wire_type != 5) fail(field.offset, std::string(name) + " is not a float");
  const std::uint32_t bits = static_cast<std::uint32_t>(field.value);
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

std::string ProtobufMessageReader::string(const ProtobufField& field) const {
  return field.wire_type == 2 ? std::string(reinterpret_cast<const char*>(field.bytes), field.size) : std::string();
}

void ProtobufMessageReader::appendFloats(const ProtobufField& field, const char* name, std::vector<float>& out) const {
  if (field.wire_type == 5) {
    out.push_back(float32(field, name));
    return;
  }
  if (field.wire_type != 2 || field.size % 4 != 0) {
    fail(field.offset, std::string(name) + " is not a list of floats");
  }
  for (std::size_t k = 0; k < field.size; k += 4) {
    float value;
    std::memcpy(&value, field.bytes + k, 4);
    out.push_back(value);
  }
}

std::vector<std::uint8_t> readBinaryFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingFormatError(path, 0, "cannot open file for reading");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw RecordingFormatError(path, 0, "read error");
  return bytes;
}

}  // namespace deep_ois
