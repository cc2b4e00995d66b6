// Writes what is readable of a rosbag without a valid index (cut short, or its writer killed:
// a fundamental_mixtures or simulate run stopped by SIGKILL) into a new indexed bag, as
// `rosbag reindex` does but without Python and without touching the damaged file. An intact bag
// is copied whole.
//
//   recover_bag DAMAGED.bag REPAIRED.bag
//
// Prints what was kept and where reading stopped. Exit status: 0 read to the end, 3 something was
// lost (the repaired bag holds every message before the damage), 1 nothing readable, 2 usage.
#include <cstdio>
#include <exception>
#include <string>

#include "deep_ois/ros/bag/bag_recovery.h"

int main(int argc, char** argv) {
  if (argc != 3 || std::string(argv[1]) == std::string(argv[2])) {
    std::fprintf(stderr, "usage: recover_bag DAMAGED.bag REPAIRED.bag (two different files)\n");
    return 2;
  }
  try {
    const deep_ois::BagRecoveryReport report = deep_ois::recoverBag(argv[1], argv[2]);
    std::printf("recover_bag: %s -> %s: %s\n", argv[1], argv[2], report.text().c_str());
    if (report.messages == 0) return 1;
    return report.stopped_because.empty() ? 0 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "recover_bag: %s\n", e.what());
    return 1;
  }
}
