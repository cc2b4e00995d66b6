// The paper's results table: mean geometry distance per method and category.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace deep_ois {

// The paper caps an error at the identity (no alignment) error of the same pair: a method that
// does worse than not aligning at all counts as not aligning.
inline double capAtIdentity(double distance_px, double identity_px) {
  return distance_px > identity_px ? identity_px : distance_px;
}

class EvaluationTable {
 public:
  // Records one frame pair's distance (pixels) for a method in a category. Methods and categories
  // are listed in the order they are first added.
  void add(const std::string& method, const std::string& category, double distance_px);
  // The paper's rule for one frame pair: records min(distance, identity) and counts the pair as
  // capped when the distance was above the identity error. Returns the recorded value.
  double addCapped(const std::string& method, const std::string& category, double distance_px,
                   double identity_px);
  // A method that gave no motion for a pair (too few matches, solver failure, a non-finite
  // result) is scored as not aligning: the identity error is recorded and the failure counted.
  void addFailure(const std::string& method, const std::string& category, double identity_px);

  // Mean over the pairs of (method, category); NaN when there is none.
  double mean(const std::string& method, const std::string& category) const;
  std::size_t count(const std::string& method, const std::string& category) const;
  // Pairs of (method, category) that addFailure / addCapped counted.
  std::size_t failures(const std::string& method, const std::string& category) const;
  std::size_t capped(const std::string& method, const std::string& category) const;
  // The paper's Avg: the mean of the per-category means (categories without pairs are left out).
  double average(const std::string& method) const;

  // Lists the named categories first, in this order (e.g. the paper's RE, LT, LL, MF), then any
  // others in the order they were added.
  void orderCategories(const std::vector<std::string>& preferred);
  // The same for the methods (rows), e.g. in the order they were registered.
  void orderMethods(const std::vector<std::string>& preferred);

  const std::vector<std::string>& methods() const { return methods_; }
  const std::vector<std::string>& categories() const { return categories_; }

  // A markdown table: one row per method, one column per category, then Avg; "-" where a method
  // has no pair in a category. Numbers with 3 decimals.
  std::string markdown() const;
  // CSV with header method,category,pairs,mean_px,failed,capped (one line per cell, plus Avg).
  std::string csv() const;

 private:
  struct Cell {
    double sum = 0.0;
    std::size_t count = 0;
    std::size_t failures = 0;
    std::size_t capped = 0;
  };
  std::size_t field(const std::string& method, const std::string& category,
                    std::size_t Cell::*member) const;
  std::vector<std::string> methods_;
  std::vector<std::string> categories_;
  std::map<std::pair<std::string, std::string>, Cell> cells_;
};

}  // namespace deep_ois
