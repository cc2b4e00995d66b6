// Identifies a data set by content, so a model's metadata says exactly what it was trained on.
#pragma once

#include <string>
#include <vector>

namespace deep_ois {

// FNV-1a 64-bit over the bytes of the files in the given order, as 16 hex digits. Not
// cryptographic: it tells data sets apart, it does not defend against tampering. Throws
// std::runtime_error naming a file that cannot be read.
std::string fnv1aHashOfFiles(const std::vector<std::string>& paths);

}  // namespace deep_ois
