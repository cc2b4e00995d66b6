// Where a test finds ../shared/data (the real recordings beside the repository): the
// DEEP_OIS_SHARED_DATA environment variable when set, else the folder CMake found at configure time
// (DEEP_OIS_SHARED_DATA_DIR, defined for the tests that read it). Tests skip when it is absent.
#pragma once

#include <cstdlib>
#include <string>

namespace deep_ois {

inline std::string sharedData(const std::string& name) {
  const char* override_dir = std::getenv("DEEP_OIS_SHARED_DATA");
  const std::string base = override_dir && *override_dir ? override_dir : DEEP_OIS_SHARED_DATA_DIR;
  return base + "/" + name;
}

}  // namespace deep_ois
