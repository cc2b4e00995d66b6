// A PNG contact sheet of the simulator: one row per category (RE, LT, LL, MF) with frame a,
// frame b and the ghost overlay (red channel of b over a: misalignment shows as colour fringes).
// Flags: --help.
#include <ros/package.h>

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/sim/simulator.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

// A panel with a caption strip above it.
cv::Mat captioned(const cv::Mat& rgb, const std::string& caption) {
  cv::Mat panel(rgb.rows + 22, rgb.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  rgb.copyTo(panel(cv::Rect(0, 22, rgb.cols, rgb.rows)));
  cv::putText(panel, caption, cv::Point(4, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0),
              1, cv::LINE_AA);
  return panel;
}

}  // namespace

constexpr char kDescription[] =
    "Draws a PNG contact sheet of the simulator: one row per category (RE, LT, LL, MF) with frame "
    "a, "
    "frame b and the ghost overlay (red channel of b over a: misalignment shows as colour "
    "fringes).";

int main(int argc, char** argv) {
  // The installed package's configs (or the source tree's, when run from the devel space).
  std::string out, config_dir = ros::package::getPath("deep_ois") + "/config/simulator";
  std::uint32_t seed = 1;
  deep_ois::ToolCommandLine command_line("sim_contact_sheet", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--out", out, "the sheet, e.g. docs/simulator_contact_sheet.png")
      ->required()
      ->type_name("FILE.png");
  command_line.addNumber("--seed", seed, "the simulator's seed");
  app.add_option("--config-dir", config_dir, "folder with RE.yaml, LT.yaml, LL.yaml and MF.yaml")
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  try {
    std::vector<cv::Mat> rows;
    for (const char* name : {"RE", "LT", "LL", "MF"}) {
      const deep_ois::sim::SimulatorConfig config =
          deep_ois::sim::loadSimulatorConfig(config_dir + "/" + name + ".yaml");
      const deep_ois::sim::Simulator simulator(config, static_cast<std::uint32_t>(seed), 0.5);
      const int k = 10;  // a pair well inside the sequence
      const cv::Mat a = simulator.renderFrame(k - 1), b = simulator.renderFrame(k);
      const std::string label = std::string(name) + (config.ois.enabled ? " (OIS on)" : "");
      std::vector<cv::Mat> panels = {
          captioned(a, label + ": frame a"), captioned(b, "frame b"),
          captioned(deep_ois::ghostOverlay(a, b), "ghost: red of b over a")};
      cv::Mat row;
      cv::hconcat(panels, row);
      rows.push_back(row);
    }
    cv::Mat sheet, bgr;
    cv::vconcat(rows, sheet);
    cv::cvtColor(sheet, bgr, cv::COLOR_RGB2BGR);
    if (!cv::imwrite(out, bgr)) {
      std::fprintf(stderr, "sim_contact_sheet: cannot write %s\n", out.c_str());
      return 1;
    }
    std::printf("sim_contact_sheet: wrote %s (%dx%d)\n", out.c_str(), sheet.cols, sheet.rows);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_contact_sheet: %s\n", e.what());
    return 1;
  }
  return 0;
}
