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
#include <optional>
#include <string>

#include "deep_ois/ros/bag/bag_recovery.h"
#include "deep_ois/tools/support/command_line.h"

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "recover_bag",
      "Writes what is readable of a rosbag without a valid index (cut short, or its writer "
      "killed) into a new indexed bag, as `rosbag reindex` does, without touching the damaged "
      "file. An intact bag is copied whole.",
      "Exit status: 0 read to the end, 3 something was lost (the repaired bag holds every message "
      "before the damage), 1 nothing readable, 2 usage.");
  std::string damaged, repaired;
  CLI::App& app = command_line.app();
  app.add_option("damaged", damaged, "the bag to read")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("DAMAGED.bag");
  app.add_option("repaired", repaired, "the bag to write (another file)")
      ->required()
      ->type_name("REPAIRED.bag");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (damaged == repaired) return command_line.usageError("DAMAGED.bag and REPAIRED.bag must differ");
  try {
    const deep_ois::BagRecoveryReport report = deep_ois::recoverBag(damaged, repaired);
    std::printf("recover_bag: %s -> %s: %s\n", damaged.c_str(), repaired.c_str(),
                report.text().c_str());
    if (report.messages == 0) return 1;
    return report.stopped_because.empty() ? 0 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "recover_bag: %s\n", e.what());
    return 1;
  }
}
