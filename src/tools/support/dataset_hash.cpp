#include "deep_ois/tools/support/dataset_hash.h"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <vector>

namespace deep_ois {

std::string fnv1aHashOfFiles(const std::vector<std::string>& paths) {
  std::uint64_t hash = 0xcbf29ce484222325ull;
  std::vector<char> buffer(1 << 20);
  for (const std::string& path : paths) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path + " to hash it");
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      const std::streamsize n = in.gcount();
      for (std::streamsize i = 0; i < n; ++i) {
        hash ^= static_cast<unsigned char>(buffer[static_cast<std::size_t>(i)]);
        hash *= 0x100000001b3ull;
      }
    }
    if (in.bad()) throw std::runtime_error("read error while hashing " + path);
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

}  // namespace deep_ois
