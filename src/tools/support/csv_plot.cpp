#include "deep_ois/tools/support/csv_plot.h"

#include <ros/package.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

namespace {
// The system python: the one Debian's python3-matplotlib installs into (a pyenv or venv python
// first on PATH would not see it).
constexpr const char* kPython = "/usr/bin/python3";
// plot_csv.py's exit status when matplotlib cannot be imported.
constexpr int kExitNoMatplotlib = 3;
// The child's status when the interpreter could not be started.
constexpr int kExitNoInterpreter = 127;

const char* roleName(PlotRole role) {
  switch (role) {
    case PlotRole::kLogged:
      return "logged";
    case PlotRole::kPredicted:
      return "predicted";
    case PlotRole::kLine:
      break;
  }
  return "line";
}

std::string formatNumber(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

// Runs kPython with `arguments` (no shell: labels may hold any character); its exit status, or
// -1 when it was killed or could not be forked.
int runPython(const std::vector<std::string>& arguments) {
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(kPython));
  for (const std::string& argument : arguments) argv.push_back(const_cast<char*>(argument.c_str()));
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t child = fork();
  if (child < 0) return -1;
  if (child == 0) {
    execv(kPython, argv.data());
    _exit(kExitNoInterpreter);
  }
  int status = 0;
  if (waitpid(child, &status, 0) != child) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}
}  // namespace

void writeCsvColumns(const std::string& path,
                     const std::vector<std::pair<std::string, std::vector<double>>>& columns) {
  const std::size_t rows = columns.empty() ? 0 : columns.front().second.size();
  for (const auto& [name, values] : columns) {
    if (values.size() != rows)
      throw std::invalid_argument(path + ": column " + name + " has " + std::to_string(values.size()) +
                                  " values, the first column " + std::to_string(rows));
  }
  std::ofstream csv(path);
  csv << std::setprecision(9);
  for (std::size_t c = 0; c < columns.size(); ++c) csv << (c ? "," : "") << columns[c].first;
  csv << "\n";
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      if (c) csv << ",";
      if (std::isfinite(columns[c].second[r])) csv << columns[c].second[r];
    }
    csv << "\n";
  }
  csv.close();
  if (!csv) throw std::runtime_error(path + ": cannot write");
}

std::string plotScriptPath() {
  const std::string package = ros::package::getPath("deep_ois");
  return package.empty() ? std::string() : package + "/scripts/plot_csv.py";
}

std::vector<std::string> plotCommand(const std::string& script, const CsvPlot& plot,
                                     const std::string& csv_path, const std::string& png_path) {
  std::vector<std::string> command = {script, csv_path, png_path};
  const bool bars = !plot.bar_label_column.empty() && !plot.bar_value_column.empty();
  if (bars) {
    command.insert(command.end(), {"--bars", plot.bar_label_column, plot.bar_value_column});
  } else {
    command.insert(command.end(), {"--x", plot.x_column});
    for (const PlotCurve& curve : plot.curves)
      command.insert(command.end(),
                     {"--series", curve.column, curve.label, roleName(curve.role), std::to_string(curve.panel)});
  }
  for (const auto& [column, value] : plot.where) command.insert(command.end(), {"--where", column + "=" + value});
  if (!plot.x_label.empty()) command.insert(command.end(), {"--x-label", plot.x_label});
  for (const std::string& label : plot.y_labels) command.insert(command.end(), {"--y-label", label});
  for (double y : plot.reference_lines) command.insert(command.end(), {"--hline", formatNumber(y)});
  if (!plot.title.empty()) command.insert(command.end(), {"--title", plot.title});
  if (plot.log_y) command.push_back("--log-y");
  command.insert(command.end(),
                 {"--size", std::to_string(plot.width_px) + "x" + std::to_string(plot.height_px)});
  return command;
}

PlotOutcome plotCsv(const CsvPlot& plot, const std::string& csv_path, const std::string& png_path) {
  PlotOutcome outcome;
  const std::string script = plotScriptPath();
  std::error_code error;
  if (script.empty()) {
    outcome.problem = "the package deep_ois is not on ROS_PACKAGE_PATH, so its scripts/plot_csv.py is "
                      "not found (source the workspace's setup.bash)";
    return outcome;
  }
  if (!std::filesystem::is_regular_file(script, error)) {
    outcome.problem = script + " is missing";
    return outcome;
  }
  if (!std::filesystem::exists(kPython, error)) {
    outcome.problem = std::string(kPython) + " is missing (install Debian's python3-matplotlib)";
    return outcome;
  }
  std::filesystem::remove(png_path, error);  // a stale PNG must not pass for this run's
  const int status = runPython(plotCommand(script, plot, csv_path, png_path));
  if (status == kExitNoMatplotlib) {
    outcome.problem = "matplotlib is missing: install Debian's python3-matplotlib";
  } else if (status == kExitNoInterpreter) {
    outcome.problem = std::string("cannot run ") + kPython;
  } else if (status != 0) {
    outcome.problem = "plot_csv.py failed (exit status " + std::to_string(status) + ")";
  } else if (!std::filesystem::is_regular_file(png_path, error)) {
    outcome.problem = "plot_csv.py wrote no " + png_path;
  } else {
    outcome.written = true;
  }
  return outcome;
}

PlotOutcome writeAndPlotCsv(const CsvPlot& plot,
                            const std::vector<std::pair<std::string, std::vector<double>>>& columns,
                            const std::string& csv_path, const std::string& png_path) {
  try {
    writeCsvColumns(csv_path, columns);
  } catch (const std::exception& e) {
    PlotOutcome outcome;
    outcome.problem = e.what();
    return outcome;
  }
  return plotCsv(plot, csv_path, png_path);
}

std::string describePlot(const PlotOutcome& outcome, const std::string& csv_path, const std::string& png_path) {
  if (outcome.written) return "wrote " + png_path;
  return "no plot " + png_path + " (" + outcome.problem + "); the data is in " + csv_path;
}

}  // namespace deep_ois
