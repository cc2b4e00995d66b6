#include "deep_ois/ros/bag/bag_recovery.h"

#include <bzlib.h>
#include <rosbag/bag.h>
#include <roslz4/lz4s.h>
#include <topic_tools/shape_shifter.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace deep_ois {
namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr std::size_t kMagicBytes = sizeof(kMagic) - 1;
// Larger headers or records than these are damage, not data (a chunk is ~768 KB by default, a
// raw 4K image ~36 MB).
constexpr std::uint32_t kMaxHeaderBytes = 16u << 20;
constexpr std::uint32_t kMaxRecordBytes = 1u << 30;

constexpr char kOpMessageData = 0x02;
constexpr char kOpChunk = 0x05;
constexpr char kOpConnection = 0x07;

std::uint32_t read32(const char* bytes) {
  std::uint32_t value = 0;
  for (int k = 3; k >= 0; --k) value = (value << 8) | static_cast<unsigned char>(bytes[k]);
  return value;
}

using Fields = std::map<std::string, std::string>;

// Header fields <u32 length>"name=value"; false when they do not tile the header exactly.
bool parseFields(const char* bytes, std::size_t size, Fields& fields) {
  fields.clear();
  for (std::size_t at = 0; at < size;) {
    if (at + 4 > size) return false;
    const std::uint32_t length = read32(bytes + at);
    at += 4;
    if (length > size - at) return false;
    const char* field = bytes + at;
    const char* equals = static_cast<const char*>(std::memchr(field, '=', length));
    if (!equals) return false;
    fields[std::string(field, equals)] = std::string(equals + 1, field + length);
    at += length;
  }
  return true;
}

struct Connection {
  std::string topic;
  boost::shared_ptr<ros::M_string> header;  // type, md5sum, message_definition, ...
};

// Reads the records of one chunk's (decompressed) content and writes its messages. Stops at the
// first record that does not fit or parse; returns false then (with *why set) and the byte
// count of the complete records in *used.
bool copyChunkRecords(const std::vector<char>& bytes, std::map<std::uint32_t, Connection>& connections,
                      rosbag::Bag& out, BagRecoveryReport& report, std::size_t* used, std::string* why) {
  Fields fields;
  std::size_t at = 0;
  *used = 0;
  while (at < bytes.size()) {
    if (bytes.size() - at < 4) return *why = "a record's header length is cut off", false;
    const std::uint32_t header_bytes = read32(&bytes[at]);
    if (header_bytes > bytes.size() - at - 4) return *why = "a record's header is cut off", false;
    if (!parseFields(&bytes[at + 4], header_bytes, fields)) return *why = "a record header is damaged", false;
    const std::size_t data_length_at = at + 4 + header_bytes;
    if (bytes.size() - data_length_at < 4) return *why = "a record's data length is cut off", false;
    const std::uint32_t data_bytes = read32(&bytes[data_length_at]);
    if (data_bytes > bytes.size() - data_length_at - 4) return *why = "a record's data is cut off", false;
    const char* data = &bytes[data_length_at + 4];
    const std::string op = fields["op"];
    if (op.size() == 1 && (op[0] == kOpConnection || op[0] == kOpMessageData) && fields["conn"].size() != 4) {
      return *why = "a record's connection id is damaged", false;
    }
    if (op.size() == 1 && op[0] == kOpConnection) {
      Fields connection_fields;
      if (!parseFields(data, data_bytes, connection_fields)) return *why = "a connection record is damaged", false;
      Connection connection;
      connection.topic = fields["topic"];
      connection.header = boost::make_shared<ros::M_string>(connection_fields.begin(), connection_fields.end());
      connections[read32(fields["conn"].data())] = connection;
    } else if (op.size() == 1 && op[0] == kOpMessageData) {
      const auto found = connections.find(read32(fields["conn"].data()));
      const std::string& time = fields["time"];
      if (found == connections.end() || time.size() != 8) return *why = "a message record is damaged", false;
      const ros::M_string& header = *found->second.header;
      auto value = [&](const char* key) {
        const auto it = header.find(key);
        return it == header.end() ? std::string() : it->second;
      };
      topic_tools::ShapeShifter message;
      message.morph(value("md5sum"), value("type"), value("message_definition"), value("latching"));
      std::vector<std::uint8_t> payload(data, data + data_bytes);
      ros::serialization::IStream stream(payload.data(), payload.size());
      message.read(stream);
      try {
        out.write(found->second.topic, ros::Time(read32(time.data()), read32(time.data() + 4)), message,
                  found->second.header);
      } catch (const rosbag::BagException& e) {
        throw std::runtime_error(std::string("cannot write the repaired bag: ") + e.what());
      }
      ++report.messages;
    }
    at = data_length_at + 4 + data_bytes;
    *used = at;
  }
  return true;
}

bool decompress(const std::string& compression, std::vector<char>& compressed, std::uint32_t size,
                std::vector<char>& out, std::string* why) {
  out.resize(size);
  if (compression == "none") {
    out.assign(compressed.begin(), compressed.end());
    return true;
  }
  unsigned int produced = size;
  if (compression == "bz2") {
    const int status =
        BZ2_bzBuffToBuffDecompress(out.data(), &produced, compressed.data(), compressed.size(), 0, 0);
    if (status != BZ_OK || produced != size) return *why = "a bz2 chunk does not decompress", false;
    return true;
  }
  if (compression == "lz4") {
    const int status = roslz4_buffToBuffDecompress(compressed.data(), compressed.size(), out.data(), &produced);
    if (status != ROSLZ4_OK || produced != size) return *why = "an lz4 chunk does not decompress", false;
    return true;
  }
  return *why = "unknown chunk compression '" + compression + "'", false;
}

}  // namespace

std::string BagRecoveryReport::text() const {
  std::ostringstream out;
  out << "kept " << messages << " messages from " << chunks << " chunks, the first " << bytes_read << " of "
      << file_bytes << " bytes";
  if (!stopped_because.empty()) out << "; the rest is lost (" << stopped_because << ")";
  return out.str();
}

BagRecoveryReport recoverBag(const std::string& damaged, const std::string& repaired) {
  std::ifstream in(damaged, std::ios::binary);
  if (!in) throw std::runtime_error(damaged + ": cannot read the file");
  BagRecoveryReport report;
  report.file_bytes = std::filesystem::file_size(damaged);
  char magic[kMagicBytes];
  if (!in.read(magic, kMagicBytes) || std::memcmp(magic, kMagic, kMagicBytes) != 0) {
    throw std::runtime_error(damaged + ": not a rosbag 2.0 file (no '#ROSBAG V2.0' line)");
  }
  rosbag::Bag out;
  try {
    out.open(repaired, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(repaired + ": cannot create the repaired bag: " + e.what());
  }
  std::map<std::uint32_t, Connection> connections;
  std::uint64_t at = kMagicBytes;
  report.bytes_read = at;
  Fields fields;
  std::vector<char> header, data, content;
  auto stop = [&](const std::string& why) {
    std::ostringstream where;
    where << why << " at byte " << at;
    report.stopped_because = where.str();
  };
  while (at < report.file_bytes) {
    const std::uint64_t left = report.file_bytes - at;
    char length[4];
    in.seekg(static_cast<std::streamoff>(at));
    if (left < 4 || !in.read(length, 4)) {
      stop("the file ends inside a record");
      break;
    }
    const std::uint32_t header_bytes = read32(length);
    if (header_bytes > kMaxHeaderBytes || header_bytes > left - 4) {
      stop(header_bytes > left - 4 ? "the file ends inside a record header" : "a record header is damaged");
      break;
    }
    header.resize(header_bytes);
    in.read(header.data(), header_bytes);
    if (!parseFields(header.data(), header_bytes, fields)) {
      stop("a record header is damaged");
      break;
    }
    if (left - 4 - header_bytes < 4 || !in.read(length, 4)) {
      stop("the file ends inside a record");
      break;
    }
    const std::uint64_t data_at = at + 8 + header_bytes;
    std::uint32_t data_bytes = read32(length);
    const std::string op = fields["op"];
    const bool chunk = op.size() == 1 && op[0] == kOpChunk;
    const std::string compression = fields["compression"];
    // A writer killed inside a chunk leaves its lengths at 0; its records run to the end of the file.
    // A file cut inside an uncompressed chunk keeps that chunk's complete records too.
    const bool open_chunk =
        chunk && ((data_bytes == 0 && fields["size"].size() == 4 && read32(fields["size"].data()) == 0) ||
                  (compression == "none" && data_bytes > report.file_bytes - data_at));
    if (open_chunk) {
      if (compression != "none") {
        stop("the last chunk was never finished (its writer stopped) and is " + compression + "-compressed");
        break;
      }
      data_bytes = static_cast<std::uint32_t>(std::min<std::uint64_t>(report.file_bytes - data_at, kMaxRecordBytes));
    } else if (data_bytes > kMaxRecordBytes || data_bytes > report.file_bytes - data_at) {
      stop(data_bytes > report.file_bytes - data_at ? "the file ends inside a record" : "a record is damaged");
      break;
    }
    if (!chunk) {
      // Bag header, index data, and from the index section on connection and chunk-info records
      // repeating what the chunks hold.
      at = data_at + data_bytes;
      report.bytes_read = at;
      continue;
    }
    data.resize(data_bytes);
    in.read(data.data(), data_bytes);
    std::string why;
    if (fields["size"].size() != 4) {
      stop("a chunk header is damaged");
      break;
    }
    const std::uint32_t size = open_chunk ? data_bytes : read32(fields["size"].data());
    if (size > kMaxRecordBytes || !decompress(compression, data, size, content, &why)) {
      stop(size > kMaxRecordBytes ? "a chunk header is damaged" : why);
      break;
    }
    ++report.chunks;
    std::size_t used = 0;
    const bool whole = copyChunkRecords(content, connections, out, report, &used, &why);
    if (open_chunk) {
      report.bytes_read = data_at + used;
      at = report.bytes_read;
      if (at < report.file_bytes) stop("the last chunk is incomplete (cut short, or its writer stopped): " + why);
      break;
    }
    if (!whole) {
      stop("chunk " + std::to_string(report.chunks) + ": " + why);
      break;
    }
    at = data_at + data_bytes;
    report.bytes_read = at;
  }
  try {
    out.close();
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(repaired + ": cannot write the repaired bag: " + e.what());
  }
  return report;
}

ReadableBag::ReadableBag(const std::string& path) : original_path_(path), read_path_(path) {
  std::string why;
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    return;
  } catch (const rosbag::BagException& e) {
    why = e.what();
  }
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error(path + ": cannot open the bag: " + why);
  // Unique per process and object: several jobs (or one job's bags) may recover at once.
  static std::atomic<unsigned> counter{0};
  const std::string copy = (std::filesystem::temp_directory_path() /
                            ("deep_ois_recovered_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) +
                             "_" + std::filesystem::path(path).filename().string()))
                               .string();
  try {
    report_ = recoverBag(path, copy);
  } catch (const std::exception& e) {
    std::remove(copy.c_str());
    throw std::runtime_error(path + ": cannot open the bag (" + why + ") nor recover it: " + e.what());
  }
  read_path_ = copy;
  note_ = path + ": the bag has no valid index (cut short, or its writer was stopped: " + why +
          "); read by scanning its chunks: " + report_.text();
}

ReadableBag::~ReadableBag() {
  if (recovered()) std::remove(read_path_.c_str());
}

std::string ReadableBag::originalNames(std::string text) const {
  if (!recovered()) return text;
  for (std::size_t at = text.find(read_path_); at != std::string::npos; at = text.find(read_path_, at)) {
    text.replace(at, read_path_.size(), original_path_);
    at += original_path_.size();
  }
  return text;
}

}  // namespace deep_ois
