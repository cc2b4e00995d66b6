// The table row of the fused motion (core/fusion/fused_motion.h): a prior row (the stabiliser
// model's compensation on an OIS camera, the plain gyro on a camera without OIS) refined per row
// patch by the pair's tracks. The evaluate tool and benchmark_fusion both add this row.
//
// Per pair: the prior row's estimate; the pair tracked with the online learner's tracker (its
// corners and KLT, on the full frame: the tracks the live pipeline already follows); fuseMotion.
// The prior's uncertainty is what the live pipeline would know before the pair: the median model
// residual of the per-pair check (compensation_check.h) over the recording's last pairs; the
// pair's own check is added after its fusion. A prior that fails fails the row (scored as
// identity, as the prior's row is).
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>

#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/fusion/fused_motion.h"
#include "deep_ois/core/online/compensation_check.h"

namespace deep_ois {

struct FusedRowOptions {
  FusionOptions fusion;
  CompensationCheckOptions check;
  std::size_t recent_checks = 10;  // the prior's sigma: median of the last checks' model residuals
  double initial_sigma_px = 0.5;   // before the recording's first usable check
  double min_sigma_px = 0.1;       // the checks' residual holds the tracks' noise; never below this
  double fixed_sigma_px = 0.0;     // > 0: this sigma on every pair instead of the checks'

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// What a fused row did, per category, and where its time went (wall seconds, one thread).
struct FusionTally {
  struct Category {
    std::size_t pairs = 0, refined = 0;
    double correction_sum_px = 0.0, given_sigma_sum_px = 0.0, used_sigma_sum_px = 0.0;
    std::map<std::string, std::size_t> kept;  // why the prior was kept (reason's kind) -> pairs
  };
  std::map<std::string, Category> categories;
  double tracking_s = 0.0, fusion_s = 0.0, check_s = 0.0;
  std::size_t pairs = 0;

  std::size_t refinedPairs() const;
  // Per category: pairs, the share refined, their mean correction, the prior's sigma given and
  // used, and why the others kept the prior; then the cost per pair. Markdown.
  std::string markdown() const;
  // One line: "N pairs, R refined (X %), mean correction Y px; tracking A ms, fusion B ms a pair".
  std::string summary() const;
};

// The fused row named `name` over the pairs of `prior_row`'s scope. `tally`, when given, is filled
// as the pairs are scored. Throws std::invalid_argument for invalid options or a prior row without
// an estimate function.
AlignmentMethod fusedAlignmentMethod(const std::string& name, AlignmentMethod prior_row,
                                     const FusedRowOptions& options = {},
                                     std::shared_ptr<FusionTally> tally = nullptr);

// The plain gyro homographies as a prior row over the cameras without OIS (annotated recordings
// said to be non-OIS or whose OIS state is not given): for them the gyro is the compensation.
AlignmentMethod gyroPriorMethod();

}  // namespace deep_ois
