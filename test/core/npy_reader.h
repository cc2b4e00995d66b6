// Test-only reader for NumPy .npy files holding little-endian float64 arrays in C order, the
// format of the authors' reference data. Anything else is refused with a message, not guessed.
#pragma once

#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace deep_ois {
namespace test {

struct NpyArray {
  std::vector<std::size_t> shape;
  std::vector<double> data;  // C order (last index fastest)

  std::size_t size() const { return data.size(); }
  // Flat index of a multi-index; no bounds check beyond the rank.
  template <typename... Index>
  double at(Index... index) const {
    static_assert(sizeof...(Index) > 0, "at() needs an index");
    const std::size_t idx[] = {static_cast<std::size_t>(index)...};
    if (sizeof...(Index) != shape.size()) throw std::out_of_range("NpyArray::at: wrong rank");
    std::size_t flat = 0;
    for (std::size_t d = 0; d < shape.size(); ++d) flat = flat * shape[d] + idx[d];
    return data.at(flat);
  }
};

namespace npy_detail {

// The value text of `key` in the header dict, e.g. "'<f8'" or "(101, 10, 9)" (trimmed).
inline std::string dictValue(const std::string& header, const std::string& key,
                             const std::string& path) {
  const std::string quoted = "'" + key + "'";
  const std::size_t k = header.find(quoted);
  if (k == std::string::npos) throw std::runtime_error(path + ": npy header lacks " + quoted);
  std::size_t begin = header.find(':', k + quoted.size());
  if (begin == std::string::npos) throw std::runtime_error(path + ": npy header malformed");
  ++begin;
  while (begin < header.size() && header[begin] == ' ') ++begin;
  if (begin >= header.size()) throw std::runtime_error(path + ": npy header malformed");
  // A tuple value runs to its closing parenthesis; anything else to the next comma or brace.
  std::size_t end =
      header[begin] == '(' ? header.find(')', begin) : header.find_first_of(",}", begin);
  if (end == std::string::npos || end <= begin) {
    throw std::runtime_error(path + ": npy header value of " + quoted + " malformed");
  }
  if (header[begin] == '(') ++end;  // keep the closing parenthesis
  while (end > begin && header[end - 1] == ' ') --end;
  return header.substr(begin, end - begin);
}

inline std::vector<std::size_t> parseShape(const std::string& tuple, const std::string& path) {
  if (tuple.size() < 2 || tuple.front() != '(' || tuple.back() != ')') {
    throw std::runtime_error(path + ": npy shape is not a tuple: " + tuple);
  }
  std::vector<std::size_t> shape;
  std::stringstream items(tuple.substr(1, tuple.size() - 2));
  std::string item;
  while (std::getline(items, item, ',')) {
    const std::size_t first = item.find_first_not_of(' ');
    if (first == std::string::npos) continue;  // trailing comma of a 1-tuple
    std::size_t used = 0;
    unsigned long long value = 0;
    try {
      value = std::stoull(item.substr(first), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || item.find_first_not_of(' ', first + used) != std::string::npos) {
      throw std::runtime_error(path + ": npy shape entry '" + item + "' is not an integer");
    }
    shape.push_back(static_cast<std::size_t>(value));
  }
  return shape;
}

}  // namespace npy_detail

// Reads `path`; throws std::runtime_error naming the file and the problem.
inline NpyArray readNpyFloat64(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open");
  char magic[8];
  if (!in.read(magic, 8) || std::memcmp(magic, "\x93NUMPY", 6) != 0) {
    throw std::runtime_error(path + ": not a .npy file (bad magic)");
  }
  const int major = static_cast<unsigned char>(magic[6]);
  if (major < 1 || major > 3) {
    throw std::runtime_error(path + ": unsupported npy version " + std::to_string(major));
  }
  // Version 1 stores the header length in 2 bytes, versions 2 and 3 in 4, little-endian.
  const int len_size = major == 1 ? 2 : 4;
  unsigned char len_bytes[4] = {0, 0, 0, 0};
  std::uint32_t header_len = 0;
  if (!in.read(reinterpret_cast<char*>(len_bytes), len_size)) {
    throw std::runtime_error(path + ": truncated npy header");
  }
  for (int i = len_size - 1; i >= 0; --i) header_len = (header_len << 8) | len_bytes[i];
  std::string header(header_len, '\0');
  if (!in.read(&header[0], header_len)) throw std::runtime_error(path + ": truncated npy header");

  const std::string descr = npy_detail::dictValue(header, "descr", path);
  if (descr != "'<f8'") {
    throw std::runtime_error(path + ": npy descr is " + descr + ", only '<f8' is supported");
  }
  const std::string fortran = npy_detail::dictValue(header, "fortran_order", path);
  if (fortran != "False") {
    throw std::runtime_error(path + ": npy fortran_order is " + fortran + ", only C order");
  }
  NpyArray array;
  array.shape = npy_detail::parseShape(npy_detail::dictValue(header, "shape", path), path);
  std::size_t count = 1;
  for (std::size_t n : array.shape) count *= n;

  // The payload is little-endian IEEE 754; reassemble bytes so a big-endian host reads it too.
  std::vector<unsigned char> bytes(count * 8);
  if (count > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), bytes.size())) {
    throw std::runtime_error(path + ": npy payload shorter than shape needs (" +
                             std::to_string(count) + " doubles)");
  }
  array.data.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::uint64_t bits = 0;
    for (int b = 7; b >= 0; --b) bits = (bits << 8) | bytes[i * 8 + b];
    std::memcpy(&array.data[i], &bits, sizeof(double));
  }
  return array;
}

}  // namespace test
}  // namespace deep_ois
