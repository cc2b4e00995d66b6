// The evaluator: reads recordings (rosbags), runs every registered alignment method on their
// annotated frame pairs and scores them with the paper's geometry distance, capped at identity.
// The evaluate tool is a thin shell over this class; methods are pluggable
// (core/evaluation/table_row_method.h), the standard rows are in core/evaluation/standard_table_rows.h.
//
// Pairs come from the simulator's /ground_truth/frame_pair messages (category, OIS on/off,
// annotated correspondences) or, for real recordings without truth, from a user annotation file
// (core/evaluation/annotation_file.h) matched to the bag's frames by exact stamps. The gyro input of every
// pair is the gyro flow nodelet's code with the nodelet's parameters.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/evaluation/table_row_method.h"
#include "deep_ois/core/evaluation/annotation_file.h"
#include "deep_ois/tools/support/evaluation_report.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"

namespace deep_ois {

struct EvaluationOptions {
  std::vector<std::string> bags;  // scored in this order
  BagSequenceTopics topics;
  // The gyro flow nodelet's parameters (config/gyro_flow.yaml): the gyro homographies and the gyro
  // flow grid of every pair are exactly what the nodelet would publish.
  GyroFlowParameters gyro;
  // When set, pairs come from this file instead of /ground_truth/frame_pair, and all its pairs
  // have `annotated_scope` (kOisCameraPairs, kNonOisCameraPairs or kUnspecifiedCameraPairs: it
  // names the gyro row and selects the methods for OIS cameras).
  std::optional<AnnotationFile> annotations;
  PairScope annotated_scope = kUnspecifiedCameraPairs;
  // Ghost images: per category, the middle pair of each recording until this many (0 = none).
  int ghost_pairs_per_category = 3;
  // Ghost panels show the centre 1/zoom of the frame magnified zoom times (1 = the whole frame):
  // the errors to see are around a pixel.
  int ghost_zoom = 2;
  std::size_t max_pairs_per_bag = 0;  // score only the first pairs of each bag (0 = all)
  bool show_progress = true;          // a progress bar on stderr

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// True when a bag holds the camera's lens-shift log (topics.lens_shift_log) and the gyro flow config
// uses it (use_lens_shift_log): the "gyro + lens log" row then has pairs to score.
bool recordingsHaveLensShiftLog(const EvaluationOptions& options);

class EvaluationRunner {
 public:
  // Throws std::invalid_argument when the options are invalid.
  explicit EvaluationRunner(EvaluationOptions options);

  // Table rows in the order added. Throws std::invalid_argument on an empty or repeated name, an
  // empty scope or a missing estimate function.
  void addMethod(AlignmentMethod method);
  void addMethods(std::vector<AlignmentMethod> methods);
  const std::vector<AlignmentMethod>& methods() const { return methods_; }

  // Scores every bag. A recording that cannot be read (missing, truncated, without camera_info,
  // IMU transform or truth) is reported in the report's recordings with its error and costs only
  // itself; annotated pairs that match no frame are reported in errors. A method that throws or
  // returns no estimate for a pair is scored as identity there and counted. Categories are in
  // the paper's order (RE, LT, LL, MF, then others), rows in the order added.
  EvaluationReport run();

 private:
  EvaluationOptions options_;
  std::vector<AlignmentMethod> methods_;
};

}  // namespace deep_ois
