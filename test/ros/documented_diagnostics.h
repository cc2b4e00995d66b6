// The /diagnostics keys docs/ros_api.md documents for each live nodelet (the tables "### <nodelet>
// keys" under "## Diagnostics"), and the comparison with the keys a running nodelet published
// (issue 31: the compensation's list had drifted: three keys that only the network publishes were
// listed as if always there, `model kind` and `warp_threads` were missing).
//
// A row is `| `key`, `key` | published | value |`. A key may end in a placeholder (`dropped:
// <reason>`): any key with that prefix matches it. The "published" cell says when the keys appear:
// "always..." means from the first status on, and "(network)" or "(stabiliser model)" restricts a
// row to that kind of model.
#pragma once

#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace deep_ois {

struct DocumentedDiagnosticsKey {
  std::string key;         // as written, placeholder included
  std::string published;   // the "published" cell
  std::string model_kind;  // "network", "stabiliser model", or "" (any model)
  bool always = false;     // published from the first status (with its model kind)
};

// The rows of the table under "### <nodelet> keys" (e.g. "deep_ois/compensation") of the
// "## Diagnostics" section of the file; empty when there is no such table.
inline std::vector<DocumentedDiagnosticsKey> documentedDiagnosticsKeys(const std::string& docs_path,
                                                                       const std::string& nodelet) {
  std::ifstream in(docs_path);
  std::vector<DocumentedDiagnosticsKey> keys;
  bool in_diagnostics = false, in_table = false;
  const std::regex key_pattern("`([^`]+)`");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) {
      in_diagnostics = line == "## Diagnostics";
      in_table = false;
    } else if (line.rfind("### ", 0) == 0) {
      in_table = in_diagnostics && line == "### " + nodelet + " keys";
    } else if (in_table && line.rfind("| `", 0) == 0) {
      std::vector<std::string> cells;
      std::stringstream row(line.substr(1));
      for (std::string cell; std::getline(row, cell, '|');) cells.push_back(cell);
      if (cells.size() < 2) continue;
      DocumentedDiagnosticsKey documented;
      documented.published = cells[1];
      while (!documented.published.empty() && documented.published.front() == ' ') documented.published.erase(0, 1);
      documented.always = documented.published.rfind("always", 0) == 0;
      if (documented.published.find("(network)") != std::string::npos) documented.model_kind = "network";
      if (documented.published.find("(stabiliser model)") != std::string::npos) documented.model_kind = "stabiliser model";
      for (std::sregex_iterator it(cells[0].begin(), cells[0].end(), key_pattern), end; it != end; ++it) {
        documented.key = (*it)[1];
        keys.push_back(documented);
      }
    }
  }
  return keys;
}

// Whether a published key is the documented one (or has the documented prefix before a placeholder).
inline bool matchesDocumentedKey(const std::string& documented, const std::string& published) {
  const std::size_t placeholder = documented.find('<');
  if (placeholder == std::string::npos) return documented == published;
  return published.size() > placeholder && published.compare(0, placeholder, documented, 0, placeholder) == 0;
}

// What disagrees between the documented keys and the keys a nodelet published over a run with a
// model of `model_kind` ("network" or "stabiliser model"), one sentence per problem.
inline std::vector<std::string> diagnosticsKeyProblems(const std::vector<DocumentedDiagnosticsKey>& documented,
                                                       const std::set<std::string>& published,
                                                       const std::string& nodelet, const std::string& model_kind) {
  std::vector<std::string> problems;
  for (const std::string& key : published) {
    const DocumentedDiagnosticsKey* row = nullptr;
    for (const DocumentedDiagnosticsKey& d : documented) {
      if (matchesDocumentedKey(d.key, key)) row = &d;
    }
    if (!row) {
      problems.push_back(nodelet + " publishes '" + key + "' (with the " + model_kind +
                         "), which docs/ros_api.md does not list");
    } else if (!row->model_kind.empty() && row->model_kind != model_kind) {
      problems.push_back(nodelet + " publishes '" + key + "' with the " + model_kind +
                         ", but docs/ros_api.md says it appears only with the " + row->model_kind);
    }
  }
  for (const DocumentedDiagnosticsKey& d : documented) {
    const bool applies = d.model_kind.empty() || d.model_kind == model_kind;
    if (d.always && applies && !published.count(d.key)) {
      problems.push_back("docs/ros_api.md says " + nodelet + " always publishes '" + d.key +
                         "' (published: " + d.published + "), but it did not with the " + model_kind);
    }
  }
  return problems;
}

}  // namespace deep_ois
