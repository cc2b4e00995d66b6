// What one evaluation run produced, and how it is written: the paper's markdown table (stdout),
// evaluation.csv, evaluation.json, evaluation_pairs.csv, a bar chart per category and ghost-image
// grids (PNG).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/evaluation/results_table.h"
#include "deep_ois/tools/support/evaluation_plots.h"

namespace deep_ois {

// One method's result on one frame pair.
struct PairScore {
  std::size_t recording = 0;  // index into EvaluationReport::recordings
  std::int64_t stamp_a_ns = 0;
  std::int64_t stamp_b_ns = 0;
  std::string category;
  std::string method;
  double distance_px = 0.0;  // the method's own distance; NaN when it gave no estimate
  double identity_px = 0.0;  // the pair's identity distance (the cap)
  double scored_px = 0.0;    // what the table counts: capped, identity for a failure
  std::string failure;       // why there is no estimate; empty otherwise
};

// One input recording.
struct RecordingOutcome {
  std::string path;
  std::size_t pairs_scored = 0;
  std::size_t pairs_skipped = 0;                    // pairs no method could be scored on
  std::map<std::string, std::size_t> skip_reasons;  // reason -> pairs
  std::string error;  // why the recording failed; empty when it did not
  // The recording's camera (camera_info, the gyro config's readout), to compare with the camera a
  // model was trained for; unknown when the recording could not be read.
  CameraDescription camera;
};

struct EvaluationReport {
  EvaluationTable table;  // capped means per method and category (failures scored as identity)
  std::vector<RecordingOutcome> recordings;
  std::vector<std::string>
      errors;  // problems outside a single recording, e.g. unmatched annotations
  std::vector<PairScore> pairs;
  // Failures per method by reason, e.g. "SIFT + RANSAC" -> {"too few matches (< 8)": 12}.
  std::map<std::string, std::map<std::string, std::size_t>> failure_reasons;
  std::vector<GhostSample> ghosts;
  // Every row registered, with its PairScope flags (the runner's methods, in order): a row for
  // OIS cameras compensates the gyro; one for all pairs sees the images.
  std::vector<std::pair<std::string, unsigned>> method_scopes;
  double elapsed_s = 0.0;  // the whole run
  double reading_s = 0.0;  // reading and decoding the recordings (ahead, overlapping the rest)
  std::map<std::string, double> method_s;  // of which each method's estimates (scoring excluded)

  // True when every recording was read and every annotated pair found.
  bool complete() const;
  std::size_t failedRecordings() const;

  // The same means without the paper's cap: every pair's own distance (a failure still counts as
  // identity). The cap hides how far a method that is worse than not aligning is off.
  EvaluationTable uncappedTable() const;
  // Per row other than the two gyro rows, the share of the gap between the uncompensated OIS gyro
  // and the non-OIS twin that the row closed, on the Avg, capped and uncapped:
  // 100 (gyro_OIS - row) / (gyro_OIS - gyro_non-OIS). Empty unless both gyro rows are present.
  // A row that compensates the gyro of an OIS camera (scope OIS camera pairs only) cannot beat
  // the non-OIS twin's gyro by more than noise: the twin is what a perfect compensation gives.
  // `beyond_twin` marks such a row above kMostGapClosedPercent, a sign that the gyro config
  // (time offset, readout) does not fit the recordings and the model absorbed the error.
  static constexpr double kMostGapClosedPercent = 110.0;
  struct GapClosed {
    std::string method;
    double capped_percent = 0.0;
    double uncapped_percent = 0.0;
    bool beyond_twin = false;
  };
  std::vector<GapClosed> gapClosed() const;

  // Compensation rows (scope: OIS camera pairs, other than the uncompensated gyro) that no pair was
  // in scope for, e.g. on recordings annotated as of a non-OIS camera: they are not in the table.
  // The gyro reference rows are not listed (which of them has pairs depends on the recordings).
  std::vector<std::string> rowsWithoutPairs() const;

  // The capped table (the paper's), the uncapped one, the gap closed per row (with a comment on a
  // compensation beyond the twin), then a note per method that had failures or capped pairs or
  // no pair at all, and the problems.
  std::string markdown() const;
  std::string json() const;
  // One line per pair and method: recording,stamp_a,stamp_b,category,method,distance_px,
  // identity_px,scored_px,failure.
  std::string pairsCsv() const;
};

// Agreement of two rows pair by pair (replay parity: a row of flows the live nodelets published
// against the same computation offline). Compared are the pairs where both gave an estimate.
struct MethodAgreement {
  std::size_t pairs_compared = 0;
  std::size_t missing_in_second = 0;  // pairs the first row scored but the second has no estimate for
  double max_abs_difference_px = 0.0; // of the uncapped distances
};
MethodAgreement compareMethods(const EvaluationReport& report, const std::string& first, const std::string& second);

// One line on the camera a model row was trained for against the recordings it was scored on, so
// that a row is not read as the model's accuracy on its own camera when it is not: "<model>:
// trained for <camera>, the camera of every recording", "<model> was trained for <camera> but k of
// n recordings are of another camera (first: <path>: <camera>; <what differs>)", or "<model>
// records no camera (a generic model)". Recordings that could not be read are not counted.
std::string modelCameraNote(const std::string& model_name, const CameraDescription& trained,
                            const std::vector<RecordingOutcome>& recordings);

// Writes evaluation.csv, evaluation.json, evaluation_pairs.csv, bars_<category>.png per category
// plus bars_Avg.png (drawn from evaluation.csv by matplotlib, tools/support/csv_plot.h), and
// ghosts_<category>.png into `directory` (created when missing). Returns the paths written.
// Throws std::runtime_error naming the file that cannot be written. A bar chart that cannot be
// drawn (matplotlib missing) is not an error: the first reason goes to `plot_problem` when given.
std::vector<std::string> writeEvaluationReport(const EvaluationReport& report,
                                               const std::string& directory,
                                               std::string* plot_problem = nullptr);

}  // namespace deep_ois
