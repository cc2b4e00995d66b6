#include "deep_ois/core/common/output_shedding.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace deep_ois {

std::string OutputSheddingOptions::validate() const {
  if (!(shed_above_s > 0.0) || !std::isfinite(shed_above_s)) return "shed_above_s must be a positive number of seconds";
  if (!(restore_below_s >= 0.0) || !(restore_below_s < shed_above_s))
    return "restore_below_s must be at least 0 and below shed_above_s";
  if (restore_after_pairs < 1) return "restore_after_pairs must be at least 1";
  if (!(cost_smoothing > 0.0 && cost_smoothing <= 1.0)) return "cost_smoothing must be in (0, 1]";
  return {};
}

OutputShedding::OutputShedding(std::vector<std::string> outputs, const OutputSheddingOptions& options)
    : outputs_(std::move(outputs)), options_(options) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("OutputShedding: " + problem);
  if (outputs_.empty()) throw std::invalid_argument("OutputShedding: no optional output to shed");
  cost_s_.assign(outputs_.size(), 0.0);
  measured_.assign(outputs_.size(), false);
  shed_counts_.assign(outputs_.size(), 0);
  order_.resize(outputs_.size());
  std::iota(order_.begin(), order_.end(), std::size_t{0});
}

void OutputShedding::sortByCost() {
  // Costliest measured first; unmeasured (never computed: no subscriber yet) last, in given order.
  std::stable_sort(order_.begin(), order_.end(), [this](std::size_t a, std::size_t b) {
    if (measured_[a] != measured_[b]) return static_cast<bool>(measured_[a]);
    return cost_s_[a] > cost_s_[b];
  });
}

std::size_t OutputShedding::beforePair(double lag_s) {
  ++pairs_;
  if (lag_s > options_.shed_above_s) {
    calm_pairs_ = 0;
    if (level_ < outputs_.size()) {
      if (level_ == 0) sortByCost();
      ++level_;
      ++escalations_;
    }
  } else if (lag_s <= options_.restore_below_s) {
    if (level_ > 0 && ++calm_pairs_ >= options_.restore_after_pairs) {
      --level_;  // the cheapest of those shed comes back first
      calm_pairs_ = 0;
    }
  } else {
    calm_pairs_ = 0;
  }
  return level_;
}

bool OutputShedding::shed(std::size_t index, bool wanted) {
  const auto position = std::find(order_.begin(), order_.end(), index) - order_.begin();
  const bool is_shed = static_cast<std::size_t>(position) < level_;
  if (is_shed && wanted) ++shed_counts_[index];
  return is_shed;
}

void OutputShedding::measured(std::size_t index, double seconds) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) return;
  cost_s_[index] = measured_[index] ? (1.0 - options_.cost_smoothing) * cost_s_[index] + options_.cost_smoothing * seconds
                                    : seconds;
  measured_[index] = true;
}

std::string OutputShedding::describeOrder() const {
  std::vector<std::size_t> order = order_;
  if (level_ == 0) {
    // Not shedding: the order it would take now.
    std::stable_sort(order.begin(), order.end(), [this](std::size_t a, std::size_t b) {
      if (measured_[a] != measured_[b]) return static_cast<bool>(measured_[a]);
      return cost_s_[a] > cost_s_[b];
    });
  }
  std::string text;
  for (std::size_t index : order) {
    char item[160];
    if (measured_[index])
      std::snprintf(item, sizeof item, "%s%s %.2f ms", text.empty() ? "" : ", ", outputs_[index].c_str(),
                    1e3 * cost_s_[index]);
    else
      std::snprintf(item, sizeof item, "%s%s (not measured yet)", text.empty() ? "" : ", ", outputs_[index].c_str());
    text += item;
  }
  return text;
}

std::string OutputShedding::describeShed() const {
  if (level_ == 0) return "nothing";
  std::string text;
  for (std::size_t k = 0; k < level_; ++k) text += (k ? ", " : "") + outputs_[order_[k]];
  return text;
}

std::string OutputShedding::describeCounts() const {
  std::string text;
  for (std::size_t index = 0; index < outputs_.size(); ++index)
    text += (index ? ", " : "") + outputs_[index] + " " + std::to_string(shed_counts_[index]);
  return text + " of " + std::to_string(pairs_) + " pairs (" + std::to_string(escalations_) + " times one more shed)";
}

}  // namespace deep_ois
