// The data-set hash is the SHA-256 a user gets from `cat a.bag b.bag | sha256sum`.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include "deep_ois/tools/support/dataset_hash.h"

namespace {

std::string writeFile(const std::string& name, const std::string& bytes) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

// What the sha256sum command prints for the files concatenated, the digest only.
std::string sha256sumOf(const std::string& paths) {
  FILE* pipe = popen(("cat " + paths + " | sha256sum").c_str(), "r");
  if (!pipe) return "";
  char line[128] = {0};
  const bool read = std::fgets(line, sizeof(line), pipe) != nullptr;
  pclose(pipe);
  return read ? std::string(line).substr(0, 64) : "";
}

TEST(DatasetHash, IsTheSha256OfAbc) {
  // FIPS 180-2, appendix B.1.
  EXPECT_EQ(deep_ois::sha256OfFiles({writeFile("hash_abc.txt", "abc")}),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  // Split over two files: the bytes concatenated, not one digest per file.
  EXPECT_EQ(deep_ois::sha256OfFiles({writeFile("hash_a.txt", "a"), writeFile("hash_bc.txt", "bc")}),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(deep_ois::sha256OfFiles({writeFile("hash_empty.txt", "")}),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(DatasetHash, MatchesSha256sumOnFilesLargerThanItsReadBuffer) {
  std::mt19937 rng(5);
  std::string first(3 * (1 << 20) + 12345, '\0'), second(777, '\0');
  for (char& c : first) c = static_cast<char>(rng());
  for (char& c : second) c = static_cast<char>(rng());
  const std::string a = writeFile("hash_big_a.bin", first), b = writeFile("hash_big_b.bin", second);
  const std::string expected = sha256sumOf(a + " " + b);
  ASSERT_EQ(expected.size(), 64u) << "sha256sum did not run";
  EXPECT_EQ(deep_ois::sha256OfFiles({a, b}), expected);
  // The order matters, as for cat.
  EXPECT_NE(deep_ois::sha256OfFiles({b, a}), expected);
}

TEST(DatasetHash, NamesAFileItCannotRead) {
  const std::string missing = ::testing::TempDir() + "/hash_no_such_file.bag";
  try {
    deep_ois::sha256OfFiles({missing});
    ADD_FAILURE() << "a missing file was hashed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
}

}  // namespace
