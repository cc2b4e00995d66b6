#include "deep_ois/core/fusion/fusion_prior_sigma.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"

namespace deep_ois {

std::string FusionPriorSigmaOptions::validate() const {
  if (recent_checks == 0) return "recent_checks must be at least 1";
  if (!(initial_sigma_px > 0.0) || !std::isfinite(initial_sigma_px)) return "initial_sigma_px must be positive";
  if (!(min_sigma_px > 0.0) || !std::isfinite(min_sigma_px)) return "min_sigma_px must be positive";
  return "";
}

FusionPriorSigma::FusionPriorSigma(FusionPriorSigmaOptions options) : options_(options) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("fusion prior sigma: " + problem);
}

void FusionPriorSigma::add(const CompensationCheck& check) {
  if (!check.usable || !std::isfinite(check.model_residual_px)) return;
  recent_residuals_px_.push_back(check.model_residual_px);
  if (recent_residuals_px_.size() > options_.recent_checks) recent_residuals_px_.pop_front();
}

double FusionPriorSigma::sigmaPx() const {
  if (recent_residuals_px_.empty()) return options_.initial_sigma_px;
  return std::max(options_.min_sigma_px,
                  median(std::vector<double>(recent_residuals_px_.begin(), recent_residuals_px_.end())));
}

}  // namespace deep_ois
