#include "deep_ois/tools/support/evaluation_report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "deep_ois/core/evaluation/annotation_file.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/tools/support/csv_plot.h"

namespace deep_ois {
namespace {

// Keys in the order written below (the report reads top-down: metric, categories, methods, ...).
using Json = nlohmann::ordered_json;

// A number, or null where there is none (a method with no pair in any category has no average).
Json jsonNumber(double value) { return std::isfinite(value) ? Json(value) : Json(nullptr); }

std::string csvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::size_t methodTotal(const EvaluationTable& table, const std::string& method,
                        std::size_t (EvaluationTable::*field)(const std::string&,
                                                              const std::string&) const) {
  std::size_t total = 0;
  for (const std::string& category : table.categories()) total += (table.*field)(method, category);
  return total;
}

void writeText(const std::string& path, const std::string& text,
               std::vector<std::string>& written) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error(path + ": cannot write");
  written.push_back(path);
}

void writePng(const std::string& path, const cv::Mat& rgb, std::vector<std::string>& written) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bool ok = false;
  try {
    ok = cv::imwrite(path, bgr);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(path + ": cannot write: " + e.what());
  }
  if (!ok) throw std::runtime_error(path + ": cannot write");
  written.push_back(path);
}

// A file name part from a category (free text in annotation files).
std::string fileSafe(const std::string& text) {
  std::string safe;
  for (const char c : text)
    safe += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return safe.empty() ? "_" : safe;
}

}  // namespace

std::size_t EvaluationReport::failedRecordings() const {
  std::size_t failed = 0;
  for (const RecordingOutcome& recording : recordings) failed += recording.error.empty() ? 0 : 1;
  return failed;
}

bool EvaluationReport::complete() const { return failedRecordings() == 0 && errors.empty(); }

EvaluationTable EvaluationReport::uncappedTable() const {
  EvaluationTable uncapped;
  for (const PairScore& pair : pairs) {
    uncapped.add(pair.method, pair.category,
                 std::isfinite(pair.distance_px) ? pair.distance_px : pair.identity_px);
  }
  uncapped.orderCategories(table.categories());
  uncapped.orderMethods(table.methods());
  return uncapped;
}

std::vector<EvaluationReport::GapClosed> EvaluationReport::gapClosed() const {
  std::vector<GapClosed> rows;
  const auto& methods = table.methods();
  auto has = [&methods](const char* name) {
    return std::find(methods.begin(), methods.end(), name) != methods.end();
  };
  if (!has(kGyroOisMethod) || !has(kGyroNonOisMethod)) return rows;
  const EvaluationTable uncapped = uncappedTable();
  auto share = [](const EvaluationTable& t, const std::string& method) {
    const double ois = t.average(kGyroOisMethod), twin = t.average(kGyroNonOisMethod);
    return 100.0 * (ois - t.average(method)) / (ois - twin);
  };
  for (const std::string& method : methods) {
    if (method == kGyroOisMethod || method == kGyroNonOisMethod || method == kIdentityMethod)
      continue;
    GapClosed row{method, share(table, method), share(uncapped, method), false};
    const auto scope = std::find_if(method_scopes.begin(), method_scopes.end(),
                                    [&](const auto& entry) { return entry.first == method; });
    const bool compensation = scope != method_scopes.end() && scope->second == kOisCameraPairs;
    row.beyond_twin =
        compensation && std::max(row.capped_percent, row.uncapped_percent) > kMostGapClosedPercent;
    rows.push_back(row);
  }
  return rows;
}

std::vector<std::string> EvaluationReport::rowsWithoutPairs() const {
  std::vector<std::string> rows;
  const auto& methods = table.methods();
  for (const auto& [method, scope] : method_scopes) {
    // The gyro reference rows depend on the kind of recording (twins, annotated, said to be OIS or
    // not): one without pairs is expected. A compensation row without pairs is not.
    if (scope != kOisCameraPairs || method == kGyroOisMethod) continue;
    if (std::find(methods.begin(), methods.end(), method) == methods.end()) rows.push_back(method);
  }
  return rows;
}

std::string EvaluationReport::markdown() const {
  std::ostringstream out;
  out << table.markdown();
  if (!pairs.empty()) {
    out << "\nUncapped (each pair's own distance; the paper caps it at identity):\n\n"
        << uncappedTable().markdown();
  }
  const std::vector<GapClosed> gaps = gapClosed();
  if (!gaps.empty()) {
    out << "\nGap closed between the uncompensated OIS gyro and the non-OIS twin (Avg):\n\n";
    char line[256];
    for (const GapClosed& gap : gaps) {
      std::snprintf(line, sizeof(line), "- %s: %.1f %% capped, %.1f %% uncapped",
                    gap.method.c_str(), gap.capped_percent, gap.uncapped_percent);
      out << line;
      if (gap.beyond_twin) {
        out << " (implausible: a compensation of the gyro cannot do better than the non-OIS "
               "twin's gyro; the gyro config's time offset or readout likely does not fit these "
               "recordings, which makes the gyro rows worse, and the model absorbed the error: "
               "check it with calibrate)";
      }
      out << "\n";
    }
  }
  std::vector<std::string> notes;
  for (const std::string& method : table.methods()) {
    const std::size_t pairs = methodTotal(table, method, &EvaluationTable::count);
    const std::size_t failed = methodTotal(table, method, &EvaluationTable::failures);
    const std::size_t capped = methodTotal(table, method, &EvaluationTable::capped);
    if (failed == 0 && capped == 0) continue;
    std::ostringstream note;
    note << "- " << method << ": " << pairs << " pairs";
    if (failed > 0) {
      note << "; " << failed << " without an estimate, scored as identity (";
      const auto reasons = failure_reasons.find(method);
      bool first = true;
      if (reasons != failure_reasons.end()) {
        for (const auto& [reason, count] : reasons->second) {
          note << (first ? "" : ", ") << reason << ": " << count;
          first = false;
        }
      }
      note << ")";
    }
    if (capped > 0) note << "; " << capped << " worse than identity, capped";
    notes.push_back(note.str());
  }
  for (const std::string& method : rowsWithoutPairs()) {
    notes.push_back("- " + method +
                    ": no pair of these recordings is in its scope (it compensates an OIS camera's "
                    "gyro: pairs of an OIS camera); left out of the table");
  }
  if (!notes.empty()) {
    out << "\n";
    for (const std::string& note : notes) out << note << "\n";
  }
  for (const RecordingOutcome& recording : recordings) {
    if (!recording.error.empty()) out << "\n**not scored**: " << recording.error << "\n";
  }
  for (const std::string& error : errors) out << "\n**error**: " << error << "\n";
  return out.str();
}

std::string EvaluationReport::json() const {
  Json root;
  root["metric"] =
      "geometry distance |p_a + flow(p_a) - p_b| in pixels, mean over the points of a pair, then "
      "over the pairs of a category; each pair capped at its identity error, a method without an "
      "estimate scored as identity; avg = mean of the category means";
  root["categories"] = table.categories();
  Json methods = Json::array();
  for (const std::string& method : table.methods()) {
    Json categories = Json::object();
    for (const std::string& category : table.categories()) {
      if (table.count(method, category) == 0) continue;
      categories[category] = {{"pairs", table.count(method, category)},
                              {"mean_px", jsonNumber(table.mean(method, category))},
                              {"failed", table.failures(method, category)},
                              {"capped", table.capped(method, category)}};
    }
    const auto reasons = failure_reasons.find(method);
    methods.push_back(
        {{"name", method},
         {"avg_px", jsonNumber(table.average(method))},
         {"categories", categories},
         {"failure_reasons",
          reasons == failure_reasons.end() ? Json::object() : Json(reasons->second)}});
  }
  root["methods"] = methods;
  Json recordings_json = Json::array();
  for (const RecordingOutcome& recording : recordings) {
    recordings_json.push_back(
        {{"path", recording.path},
         {"pairs_scored", recording.pairs_scored},
         {"pairs_skipped", recording.pairs_skipped},
         {"skip_reasons", Json(recording.skip_reasons)},
         {"error", recording.error.empty() ? Json(nullptr) : Json(recording.error)}});
  }
  root["recordings"] = recordings_json;
  root["errors"] = errors;
  root["elapsed_s"] = jsonNumber(elapsed_s);
  root["reading_s"] = jsonNumber(reading_s);
  Json seconds_per_method = Json::object();
  for (const auto& [method, seconds] : method_s) seconds_per_method[method] = jsonNumber(seconds);
  root["method_s"] = seconds_per_method;
  // Invalid UTF-8 in a path or category (free text) is replaced, not thrown at the end of a run.
  return root.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

std::string EvaluationReport::pairsCsv() const {
  std::ostringstream out;
  out << std::setprecision(6)
      << "recording,stamp_a,stamp_b,category,method,distance_px,identity_px,scored_px,failure\n";
  for (const PairScore& pair : pairs) {
    out << csvField(pair.recording < recordings.size() ? recordings[pair.recording].path : "")
        << "," << formatStampNs(pair.stamp_a_ns) << "," << formatStampNs(pair.stamp_b_ns) << ","
        << csvField(pair.category) << "," << csvField(pair.method) << ",";
    if (std::isfinite(pair.distance_px)) out << pair.distance_px;
    out << "," << pair.identity_px << "," << pair.scored_px << "," << csvField(pair.failure)
        << "\n";
  }
  return out.str();
}

std::vector<std::string> writeEvaluationReport(const EvaluationReport& report,
                                               const std::string& directory,
                                               std::string* plot_problem) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error)
    throw std::runtime_error(directory +
                             ": cannot create the output directory: " + error.message());
  std::vector<std::string> written;
  writeText(directory + "/evaluation.csv", report.table.csv(), written);
  writeText(directory + "/evaluation.json", report.json(), written);
  writeText(directory + "/evaluation_pairs.csv", report.pairsCsv(), written);
  const EvaluationTable& table = report.table;
  std::vector<std::string> columns = table.categories();
  columns.push_back("Avg");
  for (const std::string& column : columns) {
    std::size_t methods = 0, pairs = 0;
    for (const std::string& method : table.methods()) {
      const bool average = column == "Avg";
      if (!average && table.count(method, column) == 0) continue;
      ++methods;
      if (!average) pairs = std::max(pairs, table.count(method, column));
    }
    if (methods == 0) continue;
    // evaluation.csv's rows of this column: one bar per method, in the table's order.
    CsvPlot bars;
    bars.title = column == "Avg" ? "Avg: mean of the category means"
                                 : "Category " + column + ": " + std::to_string(pairs) + " frame pairs";
    bars.x_label = "geometry distance [px], each pair capped at identity; lower is better";
    bars.bar_label_column = "method";
    bars.bar_value_column = "mean_px";
    bars.where = {{"category", column}};
    bars.width_px = 1000;
    bars.height_px = 110 + 34 * static_cast<int>(methods);
    const std::string png = directory + "/bars_" + fileSafe(column) + ".png";
    const PlotOutcome outcome = plotCsv(bars, directory + "/evaluation.csv", png);
    if (outcome.written) {
      written.push_back(png);
    } else if (plot_problem && plot_problem->empty()) {
      *plot_problem = describePlot(outcome, directory + "/evaluation.csv", png);
    }
  }
  for (const std::string& category : table.categories()) {
    std::vector<GhostSample> samples;
    std::vector<std::string> columns;  // the table's rows that have a panel here, in table order
    for (const GhostSample& sample : report.ghosts) {
      if (sample.category == category) samples.push_back(sample);
    }
    for (const std::string& method : table.methods()) {
      for (const GhostSample& sample : samples) {
        if (std::any_of(sample.panels.begin(), sample.panels.end(),
                        [&](const GhostPanel& panel) { return panel.method == method; })) {
          columns.push_back(method);
          break;
        }
      }
    }
    const cv::Mat grid = drawGhostGrid(
        "Ghosts, category " + category +
            ": red channel of frame b, moved onto frame a by each method, over frame a",
        samples, columns);
    if (!grid.empty())
      writePng(directory + "/ghosts_" + fileSafe(category) + ".png", grid, written);
  }
  return written;
}

MethodAgreement compareMethods(const EvaluationReport& report, const std::string& first, const std::string& second) {
  using PairKey = std::tuple<std::size_t, std::int64_t, std::int64_t>;
  std::map<PairKey, double> second_distance;
  for (const PairScore& pair : report.pairs) {
    if (pair.method == second && pair.failure.empty()) {
      second_distance[{pair.recording, pair.stamp_a_ns, pair.stamp_b_ns}] = pair.distance_px;
    }
  }
  MethodAgreement agreement;
  for (const PairScore& pair : report.pairs) {
    if (pair.method != first || !pair.failure.empty()) continue;
    const auto found = second_distance.find({pair.recording, pair.stamp_a_ns, pair.stamp_b_ns});
    if (found == second_distance.end()) {
      ++agreement.missing_in_second;
      continue;
    }
    ++agreement.pairs_compared;
    agreement.max_abs_difference_px =
        std::max(agreement.max_abs_difference_px, std::abs(pair.distance_px - found->second));
  }
  return agreement;
}

std::string modelCameraNote(const std::string& model_name, const CameraDescription& trained,
                            const std::vector<RecordingOutcome>& recordings) {
  if (!trained.known()) return model_name + " records no camera (a generic model)";
  std::size_t read = 0, other = 0;
  std::string first_other;
  for (const RecordingOutcome& recording : recordings) {
    if (!recording.camera.known()) continue;
    ++read;
    const std::string difference = trained.differencesTo(recording.camera);
    if (difference.empty()) continue;
    if (other++ == 0) first_other = recording.path + ": " + recording.camera.summary() + "; " + difference;
  }
  if (other == 0) {
    return model_name + ": trained for " + trained.summary() +
           (read > 0 ? ", the camera of every recording" : " (no recording was read)");
  }
  return model_name + " was trained for " + trained.summary() + " but " + std::to_string(other) + " of " +
         std::to_string(read) + " recordings are of another camera (first: " + first_other +
         "): its row is not its accuracy on the camera it was trained for";
}

}  // namespace deep_ois
