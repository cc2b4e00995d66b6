// A PNG contact sheet of the simulator: one row per category (RE, LT, LL, MF) with frame a,
// frame b and the ghost overlay (red channel of b over a: misalignment shows as colour fringes).
// With --designs-csv instead: the traces of the generated stabiliser designs' contact sheet (a few
// designs per class on one gyro, lens against gyro), drawn by scripts/plot_generated_designs.py.
// Flags: --help.
#include <ros/package.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/sim/design_traces.h"
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

// The first `per_class` designs of every class (seeds from 0), each on the same hand-held motion
// and camera gyro: `path` gets the traces, `path` with _designs before .csv the designs.
void writeDesignTraces(const std::string& path, int per_class, double duration_s) {
  namespace sim = deep_ois::sim;
  std::ofstream traces(path);
  std::string designs_path = path;
  const std::size_t dot = designs_path.rfind(".csv");
  designs_path = (dot == std::string::npos ? designs_path : designs_path.substr(0, dot)) + "_designs.csv";
  std::ofstream designs(designs_path);
  if (!traces || !designs) throw std::runtime_error("cannot write " + path + " or " + designs_path);
  traces << "design_seed,t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,lens_x_px,lens_y_px\n";
  designs << "design_seed,class,split,focal_px,features,description\n";
  sim::DesignTraceOptions options;
  options.duration_s = duration_s;
  std::map<std::string, int> written;
  int total = 0;
  const int wanted = per_class * static_cast<int>(sim::designClasses().size());
  for (std::uint32_t seed = 0; total < wanted; ++seed) {
    const sim::StabiliserDesign design = sim::generateDesign(seed);
    if (written[sim::designClass(design)] >= per_class) continue;
    ++written[sim::designClass(design)];
    ++total;
    const sim::DesignTrace trace = sim::simulateDesignTrace(seed, 1, options);
    std::string features;
    for (const std::string& tag : sim::designFeatures(design)) features += (features.empty() ? "" : " ") + tag;
    // describe() on one line, quoted (it holds commas, never a double quote).
    std::string description = sim::describe(design);
    while (!description.empty() && description.back() == '\n') description.pop_back();
    for (std::size_t at = description.find('\n'); at != std::string::npos; at = description.find('\n', at)) {
      description.replace(at, 1, "; ");
    }
    designs << seed << "," << trace.design_class << "," << sim::toString(trace.split) << ","
            << options.focal_px << "," << features << ",\"" << description << "\"\n";
    char row[256];
    for (std::size_t i = 0; i < trace.gyro.size(); ++i) {
      const Eigen::Vector3d& w = trace.gyro[i].rate_rad_s;
      std::snprintf(row, sizeof(row), "%u,%.5f,%.6f,%.6f,%.6f,%.5f,%.5f\n", seed, trace.gyro[i].stamp_s,
                    w.x(), w.y(), w.z(), trace.lens_px[i].x(), trace.lens_px[i].y());
      traces << row;
    }
  }
  if (!traces || !designs) throw std::runtime_error("could not finish writing " + path);
  std::printf("sim_contact_sheet: wrote %s and %s (%d designs, %g s each)\n", path.c_str(),
              designs_path.c_str(), total, duration_s);
}

}  // namespace

constexpr char kDescription[] =
    "Draws a PNG contact sheet of the simulator: one row per category (RE, LT, LL, MF) with frame "
    "a, "
    "frame b and the ghost overlay (red channel of b over a: misalignment shows as colour "
    "fringes). With --designs-csv instead: the traces of the generated stabiliser designs' "
    "contact sheet (the first designs of every class on one hand-held gyro: the camera gyro and "
    "the design's lens shift), which scripts/plot_generated_designs.py draws.";

int main(int argc, char** argv) {
  // The installed package's configs (or the source tree's, when run from the devel space).
  std::string out, config_dir = ros::package::getPath("deep_ois") + "/config/simulator";
  std::uint32_t seed = 1;
  deep_ois::ToolCommandLine command_line("sim_contact_sheet", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  std::string designs_csv;
  int per_class = 3;
  double design_duration_s = 8.0;
  CLI::Option* out_option =
      app.add_option("--out", out, "the sheet, e.g. docs/simulator_contact_sheet.png")
          ->type_name("FILE.png");
  app.add_option("--designs-csv", designs_csv,
                 "write the generated designs' traces here (and their list beside it, "
                 "_designs.csv) instead of the sheet")
      ->excludes(out_option)
      ->type_name("FILE.csv");
  command_line.addNumber("--designs-per-class", per_class, "designs of each class in the CSV")
      ->check(CLI::Range(1, 20));
  command_line.addNumber("--design-duration", design_duration_s, "length of each design's trace, seconds")
      ->check(deep_ois::greaterThan(0))
      ->type_name("SECONDS");
  command_line.addNumber("--seed", seed, "the simulator's seed");
  app.add_option("--config-dir", config_dir, "folder with RE.yaml, LT.yaml, LL.yaml and MF.yaml")
      ->check(deep_ois::existingDirectory())
      ->type_name("DIR");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (out.empty() && designs_csv.empty()) return command_line.usageError("--out or --designs-csv is required");
  try {
    if (!designs_csv.empty()) {
      writeDesignTraces(designs_csv, per_class, design_duration_s);
      return 0;
    }
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
