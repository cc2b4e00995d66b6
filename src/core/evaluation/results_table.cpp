#include "deep_ois/core/evaluation/results_table.h"

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

// Stable sort of `list` so that the names in `preferred` come first, in that order.
void orderBy(std::vector<std::string>& list, const std::vector<std::string>& preferred) {
  auto rank = [&](const std::string& name) {
    const auto it = std::find(preferred.begin(), preferred.end(), name);
    return it == preferred.end() ? preferred.size()
                                 : static_cast<std::size_t>(it - preferred.begin());
  };
  std::stable_sort(list.begin(), list.end(),
                   [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
}
}  // namespace

void EvaluationTable::add(const std::string& method, const std::string& category, double distance_px) {
  remember(methods_, method);
  remember(categories_, category);
  Cell& cell = cells_[{method, category}];
  cell.sum += distance_px;
  ++cell.count;
}

double EvaluationTable::addCapped(const std::string& method, const std::string& category,
                                  double distance_px, double identity_px) {
  const double recorded = capAtIdentity(distance_px, identity_px);
  add(method, category, recorded);
  if (recorded != distance_px) ++cells_[{method, category}].capped;
  return recorded;
}

void EvaluationTable::addFailure(const std::string& method, const std::string& category,
                                 double identity_px) {
  add(method, category, identity_px);
  ++cells_[{method, category}].failures;
}

void EvaluationTable::orderCategories(const std::vector<std::string>& preferred) {
  orderBy(categories_, preferred);
}

void EvaluationTable::orderMethods(const std::vector<std::string>& preferred) {
  orderBy(methods_, preferred);
}

double EvaluationTable::mean(const std::string& method, const std::string& category) const {
  const auto it = cells_.find({method, category});
  if (it == cells_.end() || it->second.count == 0) return std::numeric_limits<double>::quiet_NaN();
  return it->second.sum / static_cast<double>(it->second.count);
}

std::size_t EvaluationTable::field(const std::string& method, const std::string& category,
                                   std::size_t Cell::*member) const {
  const auto it = cells_.find({method, category});
  return it == cells_.end() ? 0 : it->second.*member;
}

std::size_t EvaluationTable::count(const std::string& method, const std::string& category) const {
  return field(method, category, &Cell::count);
}

std::size_t EvaluationTable::failures(const std::string& method,
                                      const std::string& category) const {
  return field(method, category, &Cell::failures);
}

std::size_t EvaluationTable::capped(const std::string& method, const std::string& category) const {
  return field(method, category, &Cell::capped);
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
  out << std::setprecision(6) << "method,category,pairs,mean_px,failed,capped\n";
  for (const auto& method : methods_) {
    std::size_t failed_total = 0, capped_total = 0;
    for (const auto& category : categories_) {
      if (count(method, category) == 0) continue;
      out << '"' << method << "\"," << category << "," << count(method, category) << ","
          << mean(method, category) << "," << failures(method, category) << ","
          << capped(method, category) << "\n";
      failed_total += failures(method, category);
      capped_total += capped(method, category);
    }
    out << '"' << method << "\",Avg,," << average(method) << "," << failed_total << ","
        << capped_total << "\n";
  }
  return out.str();
}

}  // namespace deep_ois
