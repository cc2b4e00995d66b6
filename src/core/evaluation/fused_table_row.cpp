#include "deep_ois/core/evaluation/fused_table_row.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <limits>
#include <stdexcept>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {
namespace {

// The kind of reason a pair kept the prior: fuseMotion's sentence without its figures.
std::string reasonKind(const std::string& reason) {
  const std::string prefix = "prior kept: ";
  std::string kind = reason.rfind(prefix, 0) == 0 ? reason.substr(prefix.size()) : reason;
  if (kind.rfind("inconsistent", 0) == 0) return "inconsistent tracks";
  if (kind.find("consistent with the prior") != std::string::npos) return "too few consistent tracks";
  if (kind.find("fit within") != std::string::npos) return "too few tracks fit";
  if (kind.find("do not improve") != std::string::npos) return "no improvement";
  return kind;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string format(const char* pattern, double a, double b = 0.0, double c = 0.0) {
  char text[256];
  std::snprintf(text, sizeof(text), pattern, a, b, c);
  return text;
}

}  // namespace

std::string FusedRowOptions::validate() const {
  const std::string fusion_problem = fusion.validate();
  if (!fusion_problem.empty()) return fusion_problem;
  if (recent_checks == 0) return "recent_checks must be at least 1";
  if (!(initial_sigma_px > 0.0) || !std::isfinite(initial_sigma_px)) return "initial_sigma_px must be positive";
  if (!(min_sigma_px > 0.0) || !std::isfinite(min_sigma_px)) return "min_sigma_px must be positive";
  if (!(fixed_sigma_px >= 0.0) || !std::isfinite(fixed_sigma_px)) return "fixed_sigma_px must be >= 0 (0: from the checks)";
  return "";
}

std::size_t FusionTally::refinedPairs() const {
  std::size_t refined = 0;
  for (const auto& entry : categories) refined += entry.second.refined;
  return refined;
}

std::string FusionTally::markdown() const {
  std::string out =
      "| category | pairs | refined | mean correction of the refined, px | prior sigma given / used, px | "
      "prior kept because |\n| --- | ---: | ---: | ---: | ---: | --- |\n";
  for (const auto& [name, c] : categories) {
    std::string kept;
    for (const auto& [reason, count] : c.kept) kept += (kept.empty() ? "" : "; ") + reason + " " + std::to_string(count);
    const double pairs_in = std::max<double>(1.0, c.pairs);
    out += "| " + name + " | " + std::to_string(c.pairs) + format(" | %.1f %% | ", 100.0 * c.refined / pairs_in) +
           format("%.3f | %.3f / %.3f | ", c.refined ? c.correction_sum_px / c.refined : 0.0,
                  c.given_sigma_sum_px / pairs_in, c.used_sigma_sum_px / pairs_in) +
           (kept.empty() ? "-" : kept) + " |\n";
  }
  if (pairs > 0) {
    out += format("\ncost per pair (wall, one thread): tracking %.2f ms, fusion %.2f ms, ", 1e3 * tracking_s / pairs,
                  1e3 * fusion_s / pairs) +
           format("per-pair check %.2f ms\n", 1e3 * check_s / pairs);
  }
  return out;
}

std::string FusionTally::summary() const {
  double correction_sum_px = 0.0;
  for (const auto& entry : categories) correction_sum_px += entry.second.correction_sum_px;
  const std::size_t refined = refinedPairs();
  const double pairs_in = std::max<double>(1.0, pairs);
  return std::to_string(pairs) + " pairs, " + std::to_string(refined) +
         format(" refined (%.1f %%), mean correction %.3f px", 100.0 * refined / pairs_in,
                refined ? correction_sum_px / refined : 0.0) +
         format("; tracking %.1f ms, fusion %.1f ms, check %.1f ms a pair", 1e3 * tracking_s / pairs_in,
                1e3 * fusion_s / pairs_in, 1e3 * check_s / pairs_in);
}

AlignmentMethod fusedAlignmentMethod(const std::string& name, AlignmentMethod prior_row,
                                     const FusedRowOptions& options, std::shared_ptr<FusionTally> tally) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("fused row " + name + ": " + problem);
  if (!prior_row.estimate) throw std::invalid_argument("fused row " + name + ": the prior row has no estimate");
  if (!tally) tally = std::make_shared<FusionTally>();
  // The tracker and the recent checks live along one recording; pairs come in recording order.
  struct State {
    FeatureTracker tracker{OnlineLearningOptions::learningCorners(), OnlineLearningOptions::learningKlt()};
    std::uint64_t recording = std::numeric_limits<std::uint64_t>::max();
    std::deque<double> recent_residuals_px;
  };
  auto state = std::make_shared<State>();
  auto prior_estimate = prior_row.estimate;
  return {name, prior_row.scope, [=](const FramePairContext& pair) {
            const AlignmentEstimate prior = prior_estimate(pair);
            if (!prior.ok()) return prior;
            if (prior.kind != AlignmentEstimate::Kind::kHomographies || !prior.undistorted_pixels) {
              return AlignmentEstimate::failed("the fused row's prior must give per-patch homographies");
            }
            if (pair.recording_id != state->recording) {
              state->recording = pair.recording_id;
              state->recent_residuals_px.clear();
            }
            double sigma_px = options.fixed_sigma_px;
            if (!(sigma_px > 0.0)) {
              const std::vector<double> recent(state->recent_residuals_px.begin(), state->recent_residuals_px.end());
              sigma_px = recent.empty() ? options.initial_sigma_px : std::max(options.min_sigma_px, median(recent));
            }
            auto start = std::chrono::steady_clock::now();
            const std::vector<FeatureMatch> matches = state->tracker.match(pair.gray_a, pair.gray_b);
            tally->tracking_s += secondsSince(start);
            start = std::chrono::steady_clock::now();
            const FusedMotion fused = fuseMotion(*pair.camera, {prior.homographies, sigma_px}, matches, options.fusion);
            tally->fusion_s += secondsSince(start);
            start = std::chrono::steady_clock::now();
            const CompensationCheck check =
                checkCompensation(*pair.camera, matches, prior.homographies, pair.gyro_homographies, options.check);
            tally->check_s += secondsSince(start);
            if (check.usable) {
              state->recent_residuals_px.push_back(check.model_residual_px);
              if (state->recent_residuals_px.size() > options.recent_checks) state->recent_residuals_px.pop_front();
            }
            FusionTally::Category& category = tally->categories[pair.category];
            ++category.pairs;
            ++tally->pairs;
            category.given_sigma_sum_px += sigma_px;
            category.used_sigma_sum_px += fused.sigma_px;
            if (fused.refined) {
              ++category.refined;
              category.correction_sum_px += fused.mean_correction_px;
            } else {
              ++category.kept[reasonKind(fused.reason)];
            }
            return AlignmentEstimate::patchHomographies(fused.homographies);
          }};
}

AlignmentMethod gyroPriorMethod() {
  return {"gyro (prior)", kNonOisCameraPairs | kUnspecifiedCameraPairs, [](const FramePairContext& pair) {
            return AlignmentEstimate::patchHomographies(pair.gyro_homographies);
          }};
}

}  // namespace deep_ois
