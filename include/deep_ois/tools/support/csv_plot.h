// PNG charts of the tools, drawn by matplotlib: a tool writes its data as CSV, then runs the
// package's scripts/plot_csv.py on it under the system python. The CSV is the result; the PNG is
// a view of it, so a machine without python3-matplotlib loses the picture, never the data.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace deep_ois {

// How a curve is drawn, so a model's output never hides the measurement under it.
enum class PlotRole {
  kLine,       // a plain curve (markers where there are few points)
  kLogged,     // a measurement: thick, dark, drawn first
  kPredicted,  // a model's output: thin, coloured, drawn over the measurement
};

struct PlotCurve {
  std::string column;  // the CSV column of y
  std::string label;   // its legend entry
  PlotRole role = PlotRole::kLine;
  int panel = 1;  // 1, 2, ...: panels stacked top to bottom, sharing the x axis
};

struct CsvPlot {
  std::string title;
  std::string x_column;
  std::string x_label;                  // with its unit, e.g. "time [s]"
  std::vector<std::string> y_labels;    // one per panel, with units
  std::vector<PlotCurve> curves;
  std::vector<double> reference_lines;  // grey dashed horizontal lines at these y values
  bool log_y = false;                   // log scale on y (non-positive values are left out)
  // A horizontal bar chart instead of curves when both are set: a bar per row, labelled by one
  // column, as long as the other (x_label names the value axis; x_column and curves unused).
  std::string bar_label_column, bar_value_column;
  // Only the rows whose column (first) holds the text (second).
  std::vector<std::pair<std::string, std::string>> where;
  int width_px = 1000;
  int height_px = 500;
};

struct PlotOutcome {
  bool written = false;
  std::string problem;  // why there is no PNG (python or matplotlib missing, a bad column...)
};

// Writes named columns of equal length as a CSV (a non-finite value is an empty cell). Throws
// std::invalid_argument when the lengths differ, std::runtime_error when the file cannot be
// written.
void writeCsvColumns(const std::string& path,
                     const std::vector<std::pair<std::string, std::vector<double>>>& columns);

// writeCsvColumns, then plotCsv: for a tool whose result is elsewhere (a model), so a CSV that
// cannot be written is returned as the problem, not thrown.
PlotOutcome writeAndPlotCsv(const CsvPlot& plot,
                            const std::vector<std::pair<std::string, std::vector<double>>>& columns,
                            const std::string& csv_path, const std::string& png_path);

// The plot script: ros::package's path of deep_ois + "/scripts/plot_csv.py" (the source folder in
// a devel space, share/deep_ois in an install); empty when the package is not found.
std::string plotScriptPath();

// The arguments after the interpreter: the script, the CSV, the PNG and the plot's options.
std::vector<std::string> plotCommand(const std::string& script, const CsvPlot& plot,
                                     const std::string& csv_path, const std::string& png_path);

// Draws `plot` from the CSV at `csv_path` into `png_path` with /usr/bin/python3 and the plot
// script; the script's own messages go to stderr. Does not throw: a missing interpreter, script
// or matplotlib, or a failed drawing, is returned as the problem.
PlotOutcome plotCsv(const CsvPlot& plot, const std::string& csv_path, const std::string& png_path);

// One line for a tool's output: "wrote PNG" or "no plot PNG (PROBLEM); the data is in CSV".
std::string describePlot(const PlotOutcome& outcome, const std::string& csv_path, const std::string& png_path);

}  // namespace deep_ois
