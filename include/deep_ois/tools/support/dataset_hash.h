// Identifies a data set by content, so a model's metadata says exactly what it was trained on.
#pragma once

#include <string>
#include <vector>

namespace deep_ois {

// SHA-256 of the bytes of the files concatenated in the given order, as 64 lowercase hex digits:
// what `cat a.bag b.bag | sha256sum` prints, so anyone can check a model's training data with a
// standard tool. Throws std::runtime_error naming a file that cannot be read.
std::string sha256OfFiles(const std::vector<std::string>& paths);

}  // namespace deep_ois
