#include "deep_ois/core/evaluation_table.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

namespace deep_ois {

namespace {
void remember(std::vector<std::string>& list, const std::string& name) {
  if (std::find(list.begin(), list.end(), name) == list.end()) list.push_back(name);
}
}  // namespace

void EvaluationTable::add(const std::string& method, const std::string& category, double distance_px) {
  remember(methods_, method);
  remember(categories_, category);
  Cell& cell = cells_[{method, category}];
  cell.sum += distance_px;
  ++cell.count;
}

void EvaluationTable::orderCategories(const std::vector<std::string>& preferred) {
  auto rank = [&](const std::string& category) {
    const auto it = std::find(preferred.begin(), preferred.end(), category);
    return it == preferred.end() ? preferred.size() : static_cast<std::size_t>(it - preferred.begin());
  };
  std::stable_sort(categories_.begin(), categories_.end(),
                   [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
}

double EvaluationTable::mean(const std::string& method, const std::string& category) const {
  const auto it = cells_.find({method, category});
  if (it == cells_.end() || it->second.count == 0) return std::numeric_limits<double>::quiet_NaN();
  return it->second.sum / static_cast<double>(it->second.count);
}

std::size_t EvaluationTable::count(const std::string& method, const std::string& category) const {
  const auto it = cells_.find({method, category});
  return it == cells_.end() ? 0 : it->second.count;
}

double EvaluationTable::average(const std::string& method) const {
  double sum = 0.0;
  int used = 0;
  for (const std::string& category : categories_) {
    const double m = mean(method, category);
    if (std::isnan(m)) continue;
    sum += m;
    ++used;
  }
  return used > 0 ? sum / used : std::numeric_limits<double>::quiet_NaN();
}

std::string EvaluationTable::markdown() const {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3);
  out << "| method |";
  for (const auto& category : categories_) out << " " << category << " |";
  out << " Avg |\n|---|";
  for (std::size_t i = 0; i <= categories_.size(); ++i) out << "---:|";
  out << "\n";
  for (const auto& method : methods_) {
    out << "| " << method << " |";
    for (const auto& category : categories_) {
      const double m = mean(method, category);
      if (std::isnan(m)) {
        out << " - |";
      } else {
        out << " " << m << " |";
      }
    }
    out << " " << average(method) << " |\n";
  }
  return out.str();
}

std::string EvaluationTable::csv() const {
  std::ostringstream out;
  out << std::setprecision(6) << "method,category,pairs,mean_px\n";
  for (const auto& method : methods_) {
    for (const auto& category : categories_) {
      if (count(method, category) == 0) continue;
      out << '"' << method << "\"," << category << "," << count(method, category) << ","
          << mean(method, category) << "\n";
    }
    out << '"' << method << "\",Avg,," << average(method) << "\n";
  }
  return out.str();
}

}  // namespace deep_ois
