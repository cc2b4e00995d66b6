// The parameter tables of docs/ros_api.md and the shipped YAML files against what the nodelets'
// loaders really read (issue 23, papercut 10: the tables had drifted: old queue sizes, four
// parameters missing). Each loader runs on an empty parameter source through RecordingParameters,
// which records every name it asks for with its default; every one must be documented in its
// nodelet's table with that default, every documented one must be read, and every one must be in
// the nodelet's YAML file. No roscore needed.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/ros/live/compensation_parameters.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/live_diagnostics.h"
#include "deep_ois/ros/live/parameter_source.h"

namespace deep_ois {
namespace {

const std::string kSource = DEEP_OIS_SOURCE_DIR;

// A YAML parameter file written for the test (an empty mapping, or `model` only).
std::string writeYaml(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

// Documented default of one parameter: the cell's text before any " (...)" note, unquoted.
std::string cleanDefault(std::string text) {
  while (!text.empty() && text.front() == ' ') text.erase(text.begin());
  const std::size_t note = text.find(" (");
  if (note != std::string::npos && text.front() != '(') text = text.substr(0, note);
  std::string out;
  for (char c : text) {
    if (c != '`') out += c;
  }
  while (!out.empty() && out.back() == ' ') out.pop_back();
  while (!out.empty() && out.front() == ' ') out.erase(out.begin());
  if (out == "\"\"") out.clear();
  return out;
}

struct Documented {
  std::string default_text;
  bool reconfigure = false;  // "yes" in the reconfigure column
};

// The "### Parameters" table under "## <section>" of docs/ros_api.md, by parameter name.
std::map<std::string, Documented> documentedParameters(const std::string& section) {
  std::ifstream in(kSource + "/docs/ros_api.md");
  EXPECT_TRUE(in.good()) << "cannot read docs/ros_api.md";
  std::map<std::string, Documented> table;
  bool in_section = false, in_parameters = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) {
      in_section = line == "## " + section;
      in_parameters = false;
    } else if (line.rfind("### ", 0) == 0) {
      in_parameters = in_section && line == "### Parameters";
    } else if (in_parameters && line.rfind("| `", 0) == 0) {
      // | `a`, `b` | 5, 2000 | unit | reconfigure | meaning |
      std::vector<std::string> cells;
      std::stringstream row(line.substr(1));
      for (std::string cell; std::getline(row, cell, '|');) cells.push_back(cell);
      if (cells.size() < 4) continue;
      const bool reconfigure = cells[3].find("yes") != std::string::npos;
      std::vector<std::string> names, defaults;
      const std::regex name_pattern("`([a-z_0-9]+)`");
      for (std::sregex_iterator it(cells[0].begin(), cells[0].end(), name_pattern), end; it != end; ++it) {
        names.push_back((*it)[1]);
      }
      std::string default_cell = cells[1];
      if (names.size() > 1) {
        std::stringstream parts(default_cell);
        for (std::string part; std::getline(parts, part, ',');) defaults.push_back(cleanDefault(part));
      }
      for (std::size_t k = 0; k < names.size(); ++k) {
        table[names[k]] = {names.size() > 1 && k < defaults.size() ? defaults[k] : cleanDefault(default_cell),
                           reconfigure};
      }
    }
  }
  return table;
}

// The keys a YAML parameter file sets; with `commented`, those it shows commented out instead
// ("# test_processing_delay: 0.0": documented there, not set).
std::set<std::string> yamlKeys(const std::string& file, bool commented = false) {
  std::set<std::string> keys;
  std::ifstream in(kSource + "/config/" + file);
  EXPECT_TRUE(in.good()) << "cannot read config/" << file;
  const std::regex key_pattern(commented ? "^# ([a-z_0-9]+): " : "^([a-z_0-9]+):");
  std::smatch match;
  for (std::string line; std::getline(in, line);) {
    if (std::regex_search(line, match, key_pattern)) keys.insert(match[1]);
  }
  return keys;
}

// The parameters a dynamic_reconfigure description (cfg/NAME.cfg) makes live-tunable.
std::set<std::string> reconfigurable(const std::string& cfg) {
  std::set<std::string> names;
  std::ifstream in(kSource + "/cfg/" + cfg);
  EXPECT_TRUE(in.good()) << "cannot read cfg/" << cfg;
  std::stringstream text;
  text << in.rdbuf();
  const std::string all = text.str();
  const std::regex add_pattern("gen\\.add\\(\"([a-z_0-9]+)\"");
  for (std::sregex_iterator it(all.begin(), all.end(), add_pattern), end; it != end; ++it) names.insert((*it)[1]);
  return names;
}

// Equal as numbers when both are numbers (0.5 and 0.50, 1 and 1.0), else as text.
bool sameDefault(const std::string& documented, const std::string& code) {
  char* end_a = nullptr;
  char* end_b = nullptr;
  const double a = std::strtod(documented.c_str(), &end_a), b = std::strtod(code.c_str(), &end_b);
  if (!documented.empty() && !code.empty() && *end_a == '\0' && *end_b == '\0') return a == b;
  return documented == code;
}

void expectDocumented(const std::string& section, const std::string& yaml_file, const std::string& cfg_file,
                      const std::vector<RecordingParameters::Read>& reads, const std::set<std::string>& required) {
  const std::map<std::string, Documented> documented = documentedParameters(section);
  const std::set<std::string> live = reconfigurable(cfg_file);
  const std::set<std::string> yaml = yamlKeys(yaml_file), commented = yamlKeys(yaml_file, true);
  ASSERT_FALSE(documented.empty()) << "no parameter table under '## " << section << "' in docs/ros_api.md";
  std::set<std::string> read_names;
  for (const RecordingParameters::Read& read : reads) {
    read_names.insert(read.name);
    const auto doc = documented.find(read.name);
    if (doc == documented.end()) {
      ADD_FAILURE() << section << ": ~" << read.name << " (default " << read.default_text
                    << ") is read by the nodelet but not in docs/ros_api.md's table";
      continue;
    }
    if (required.count(read.name)) {
      EXPECT_EQ(doc->second.default_text, "(required)") << section << ": ~" << read.name;
    } else {
      EXPECT_TRUE(sameDefault(doc->second.default_text, read.default_text))
          << section << ": ~" << read.name << " is documented with default '" << doc->second.default_text
          << "' but the nodelet's default is '" << read.default_text << "'";
    }
    EXPECT_EQ(doc->second.reconfigure, live.count(read.name) > 0)
        << section << ": ~" << read.name << ": the reconfigure column of docs/ros_api.md disagrees with cfg/"
        << cfg_file;
    if (!required.count(read.name)) {
      EXPECT_TRUE(yaml.count(read.name) || commented.count(read.name)) << section << ": ~" << read.name << " is not in config/" << yaml_file;
    }
  }
  for (const auto& [name, value] : documented) {
    EXPECT_TRUE(read_names.count(name)) << section << ": docs/ros_api.md documents ~" << name
                                        << " but the nodelet never reads it";
  }
  for (const std::string& key : yaml) {
    EXPECT_TRUE(read_names.count(key)) << "config/" << yaml_file << " sets " << key << ", which the nodelet never reads";
  }
}

TEST(ParameterDocs, GyroFlowTableMatchesTheLoader) {
  const YamlParameters empty(writeYaml("empty.yaml", "{}\n"));
  const RecordingParameters recorder(empty);
  loadGyroFlowParameters(recorder);
  loadDiagnosticPeriodS(recorder);
  ASSERT_GT(recorder.reads().size(), 20u);
  expectDocumented("deep_ois/gyro_flow", "gyro_flow.yaml", "GyroFlow.cfg", recorder.reads(), {});
}

TEST(ParameterDocs, CompensationTableMatchesTheLoader) {
  const YamlParameters model_only(writeYaml("model_only.yaml", "model: any.yaml\n"));
  const RecordingParameters recorder(model_only);
  loadCompensationParameters(recorder);
  loadDiagnosticPeriodS(recorder);
  ASSERT_GT(recorder.reads().size(), 10u);
  expectDocumented("deep_ois/compensation", "compensation.yaml", "Compensation.cfg", recorder.reads(), {"model"});
}

}  // namespace
}  // namespace deep_ois
