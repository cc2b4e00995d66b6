#include "deep_ois/tools/support/evaluation_runner.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "deep_ois/tools/support/evaluation_plots.h"
#include "deep_ois/core/flow/flow_warp.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/flow/ghost_overlay.h"
#include "deep_ois/core/flow/homography_flow.h"
#include "deep_ois/tools/support/progress_bar.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// A frame pair to score, from simulator truth or an annotation file.
struct PairToScore {
  std::int64_t stamp_a_ns = 0;
  std::int64_t stamp_b_ns = 0;
  std::string category;
  PairScope scope = kOisCameraPairs;
  std::vector<Eigen::Vector2d> points_a_px, points_b_px;
  bool ghost = false;  // draw its ghost images
};

std::string fileName(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// Messages on `topic` from the bag's index (no message is read); 0 when the bag cannot be opened
// (the run reports it when it gets there).
std::size_t indexedCount(const std::string& path, const std::string& topic) {
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    return rosbag::View(bag, rosbag::TopicQuery(topic)).size();
  } catch (const std::exception&) {
    return 0;
  }
}

// Everything the pairs of one recording share.
struct Recording {
  std::size_t index = 0;
  std::string path;
  BagSequence sequence;
  std::vector<BagFrame> frames;
  std::unordered_map<std::int64_t, std::size_t> frame_of_stamp;  // stamp (ns) -> index in frames
  ImuSampleBuffer imu{1.0};
  RollingShutterConfig rolling_shutter;
  std::unique_ptr<HomographyFlowRenderer> flow_renderer;
  // The camera's lens-shift log with the gyro flow config's convention; empty without one.
  std::optional<LensShiftLog> lens_log;
  std::size_t lens_log_refused = 0;  // samples the log refused (out of order, duplicate, non-finite)
  double reading_s = 0.0;  // wall time of loadRecording
};

// Reads a recording once (IMU, camera_info, tf, truth and every frame) and prepares what its
// pairs share. Throws std::runtime_error naming the bag and the problem.
std::unique_ptr<Recording> loadRecording(std::size_t index, const std::string& path,
                                         const EvaluationOptions& options) {
  const Clock::time_point started = Clock::now();
  auto recording = std::make_unique<Recording>();
  recording->index = index;
  recording->path = path;
  recording->sequence = readBagSequence(path, options.topics, BagReadFailure::kThrow, &recording->frames);
  const BagSequence& sequence = recording->sequence;
  const CameraModel& camera = *sequence.camera;
  auto fail = [&](const std::string& what) { throw std::runtime_error(path + ": " + what); };
  if (recording->frames.empty()) fail("no image on " + options.topics.image);
  for (std::size_t f = 0; f < recording->frames.size(); ++f) {
    const BagFrame& frame = recording->frames[f];
    if (frame.rgb.cols != camera.width() || frame.rgb.rows != camera.height()) {
      fail("frame " + std::to_string(f) + " is " + std::to_string(frame.rgb.cols) + "x" +
           std::to_string(frame.rgb.rows) + " but camera_info says " +
           std::to_string(camera.width()) + "x" + std::to_string(camera.height()));
    }
    recording->frame_of_stamp[static_cast<std::int64_t>(frame.stamp.toNSec())] = f;
  }
  recording->rolling_shutter = options.gyro.rolling_shutter;
  // The cause first: without IMU messages there is no IMU frame, hence no transform either.
  if (!sequence.imu_problem.empty()) fail(sequence.imu_problem);
  if (options.gyro.rotation_from_tf) {
    if (!sequence.imu_to_camera_rotation) {
      fail(sequence.imu_to_camera_problem +
           " (set imu_to_camera_rotation in the gyro flow config to override)");
    }
    recording->rolling_shutter.imu_to_camera_rotation = *sequence.imu_to_camera_rotation;
  }
  recording->imu = sequence.imuBuffer();
  if (options.gyro.use_lens_shift_log && !sequence.lens_shift_log.empty()) {
    recording->lens_log.emplace(options.gyro.lens_shift_max_gap_s, options.gyro.lens_shift_convention);
    for (const LensShiftLogSample& sample : sequence.lens_shift_log) {
      if (!recording->lens_log->add(sample).accepted()) ++recording->lens_log_refused;
    }
  }
  recording->flow_renderer = std::make_unique<HomographyFlowRenderer>(
      camera, options.gyro.grid_size, recording->rolling_shutter.patch_count);
  recording->reading_s = secondsSince(started);
  return recording;
}

}  // namespace

bool recordingsHaveLensShiftLog(const EvaluationOptions& options) {
  if (!options.gyro.use_lens_shift_log) return false;
  for (const std::string& path : options.bags) {
    if (indexedCount(path, options.topics.lens_shift_log) > 0) return true;
  }
  return false;
}

std::string EvaluationOptions::validate() const {
  if (bags.empty()) return "bags: at least one bag is needed";
  if (topics.image.empty() || topics.camera_info.empty() || topics.imu.empty()) {
    return "image, camera_info and imu topics must not be empty";
  }
  const std::string problem = gyro.rolling_shutter.validate();
  if (!problem.empty()) return "gyro flow parameters: " + problem;
  if (gyro.grid_size.width <= 0 || gyro.grid_size.height <= 0)
    return "gyro flow grid size must be positive";
  if (annotated_scope != kOisCameraPairs && annotated_scope != kNonOisCameraPairs &&
      annotated_scope != kUnspecifiedCameraPairs) {
    return "annotated_scope must be one of the OIS, non-OIS or unspecified camera scopes";
  }
  if (ghost_pairs_per_category < 0) return "ghost_pairs_per_category must be >= 0";
  if (ghost_zoom < 1) return "ghost_zoom must be >= 1";
  return "";
}

EvaluationRunner::EvaluationRunner(EvaluationOptions options) : options_(std::move(options)) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw std::invalid_argument("EvaluationRunner: " + problem);
}

void EvaluationRunner::addMethod(AlignmentMethod method) {
  if (method.name.empty())
    throw std::invalid_argument("EvaluationRunner::addMethod: empty method name");
  if (!method.estimate)
    throw std::invalid_argument("EvaluationRunner::addMethod: " + method.name +
                                " has no estimate function");
  if ((method.scope & (kBenchmarkPairs | kNonOisTwinPairs)) == 0) {
    throw std::invalid_argument("EvaluationRunner::addMethod: " + method.name +
                                " has an empty scope");
  }
  for (const AlignmentMethod& existing : methods_) {
    if (existing.name == method.name)
      throw std::invalid_argument("EvaluationRunner::addMethod: two methods named " + method.name);
  }
  methods_.push_back(std::move(method));
}

void EvaluationRunner::addMethods(std::vector<AlignmentMethod> methods) {
  for (AlignmentMethod& method : methods) addMethod(std::move(method));
}

namespace {

// What every method sees of a pair: its frames, the gyro flow nodelet's homographies and grid
// flow, the lens log's homographies (when the recording has a log), the annotated points.
FramePairContext pairContext(const Recording& recording, const PairToScore& pair, const BagFrame& a,
                             const BagFrame& b, const RollingShutterHomographies& gyro, double stamp_a_s,
                             double stamp_b_s) {
  const CameraModel& camera = *recording.sequence.camera;
  FramePairContext context;
  context.recording_id = recording.index;
  context.stamp_a_ns = pair.stamp_a_ns;
  context.stamp_b_ns = pair.stamp_b_ns;
  context.category = pair.category;
  context.scope = pair.scope;
  context.camera = &camera;
  context.rgb_a = a.rgb;
  context.rgb_b = b.rgb;
  context.gray_a = a.gray;
  context.gray_b = b.gray;
  context.gyro_homographies = gyro.homographies;
  context.gyro_rotations = gyro.rotations;
  context.imu = &recording.imu;
  context.rolling_shutter = &recording.rolling_shutter;
  context.stamp_a_s = stamp_a_s;
  context.stamp_b_s = stamp_b_s;
  if (recording.lens_log) {
    std::optional<std::vector<Eigen::Matrix3d>> lens = lensLogHomographies(
        camera.K(), gyro.rotations, *recording.lens_log, recording.rolling_shutter, stamp_a_s, stamp_b_s);
    if (lens) context.lens_log_homographies = std::move(*lens);
  }
  recording.flow_renderer->render(gyro.homographies, context.gyro_flow_grid);
  context.points_a_px = pair.points_a_px;
  context.points_b_px = pair.points_b_px;
  return context;
}

// One run of the evaluator over every bag: the state its steps share. The steps, in order: count
// the pairs (for the progress bar); per recording, read ahead on another thread, describe its
// camera, list its pairs (from the simulator's truth or the annotation file), choose the ghost
// pairs, and score each pair with each method; then report the annotated pairs no bag held and
// order the table.
class EvaluationRun {
 public:
  EvaluationRun(const EvaluationOptions& options, std::vector<AlignmentMethod>& methods)
      : options_(options),
        methods_(methods),
        annotated_(options.annotations.has_value()),
        annotation_used_(annotated_ ? options.annotations->pairs.size() : 0, false) {}

  EvaluationReport run();

 private:
  std::size_t countPairs() const;
  void describeRecording(const Recording& recording, RecordingOutcome& result);
  std::vector<PairToScore> pairsFromTruth(const Recording& recording) const;
  std::vector<PairToScore> pairsFromAnnotations(const Recording& recording);
  bool annotatedPointsInside(const AnnotatedPair& pair, const Recording& recording);
  void chooseGhostPairs(std::vector<PairToScore>& pairs);
  void scoreRecording(Recording& recording, RecordingOutcome& result);
  void scorePair(const Recording& recording, std::size_t p, const PairToScore& pair, RecordingOutcome& result);
  void scoreMethod(AlignmentMethod& method, const FramePairContext& context, const PairToScore& pair,
                   double identity_px, GhostSample* ghost);
  void reportUnmatchedAnnotations();
  void finish();

  const EvaluationOptions& options_;
  std::vector<AlignmentMethod>& methods_;
  const bool annotated_;
  const Clock::time_point started_ = Clock::now();
  EvaluationReport report_;
  std::vector<bool> annotation_used_;  // per pair of the annotation file: a bag held it
  std::unique_ptr<ProgressBar> progress_;
  std::size_t total_pairs_ = 0;
  std::size_t pairs_done_ = 0;
  std::map<std::string, int> ghost_samples_;  // per category
};

EvaluationReport EvaluationRun::run() {
  total_pairs_ = countPairs();
  if (options_.show_progress) progress_ = std::make_unique<ProgressBar>(total_pairs_, "pairs");

  // Reading a bag (mostly bz2 decompression) overlaps scoring the previous one: one thread reads
  // ahead, the methods run on this thread, so they need not be thread-safe.
  auto prefetch = [this](std::size_t index) {
    return std::async(std::launch::async, loadRecording, index, options_.bags[index],
                      std::cref(options_));
  };
  std::future<std::unique_ptr<Recording>> next = prefetch(0);
  for (std::size_t index = 0; index < options_.bags.size(); ++index) {
    RecordingOutcome outcome;
    outcome.path = options_.bags[index];
    report_.recordings.push_back(outcome);
    RecordingOutcome& result = report_.recordings.back();
    try {
      const std::unique_ptr<Recording> loaded = next.get();
      report_.reading_s += loaded->reading_s;
      if (index + 1 < options_.bags.size()) next = prefetch(index + 1);
      scoreRecording(*loaded, result);
    } catch (const std::exception& e) {
      // One unreadable recording must not lose the others; bag readers' messages name the file.
      if (index + 1 < options_.bags.size() && !next.valid()) next = prefetch(index + 1);
      const std::string what = e.what();
      result.error = what.rfind(result.path, 0) == 0 ? what : result.path + ": " + what;
      if (progress_ && progress_->drawing())
        std::fprintf(stderr, "\nevaluate: %s\n", result.error.c_str());
    }
  }
  reportUnmatchedAnnotations();
  finish();
  return std::move(report_);
}

// Every pair the run will meet: the annotation file's, or each bag's truth messages (from the
// bag's index) up to max_pairs_per_bag.
std::size_t EvaluationRun::countPairs() const {
  if (annotated_) return options_.annotations->pairs.size();
  std::size_t total = 0;
  for (const std::string& path : options_.bags) {
    std::size_t pairs = indexedCount(path, options_.topics.frame_pair_truth);
    if (options_.max_pairs_per_bag > 0) pairs = std::min(pairs, options_.max_pairs_per_bag);
    total += pairs;
  }
  return total;
}

// The recording's camera in the report, with the frame rate from the camera_info stamps, so a
// model of another rate is told apart; and the lens-log samples it refused.
void EvaluationRun::describeRecording(const Recording& recording, RecordingOutcome& result) {
  const BagSequence& sequence = recording.sequence;
  result.camera = describeCamera(*sequence.camera, recording.rolling_shutter.readout_time_s);
  std::vector<double> frame_stamps_s;
  for (const ros::Time& stamp : sequence.frame_stamps) frame_stamps_s.push_back(sequence.secondsSinceBase(stamp));
  result.camera.frame_rate_hz = frameRateOfStampsHz(frame_stamps_s);
  if (recording.lens_log_refused > 0) {
    report_.errors.push_back(recording.path + ": " + std::to_string(recording.lens_log_refused) + " of " +
                             std::to_string(sequence.lens_shift_log.size()) + " samples on " +
                             options_.topics.lens_shift_log +
                             " refused (out of order, duplicate or non-finite); the rest is used");
  }
}

// The simulator's truth messages of the recording, one pair each. Throws when it has none.
std::vector<PairToScore> EvaluationRun::pairsFromTruth(const Recording& recording) const {
  const BagSequence& sequence = recording.sequence;
  if (sequence.truths.empty()) {
    throw std::runtime_error(recording.path + ": no annotated frame pair on " + options_.topics.frame_pair_truth +
                             " (a recording without simulator truth needs --annotations)");
  }
  std::vector<PairToScore> pairs;
  for (const FramePairTruth& truth : sequence.truths) {
    PairToScore pair;
    pair.stamp_a_ns = static_cast<std::int64_t>(truth.previous_stamp.toNSec());
    pair.stamp_b_ns = static_cast<std::int64_t>(truth.header.stamp.toNSec());
    pair.category = truth.category;
    pair.scope = truth.ois_enabled ? kOisCameraPairs : kNonOisTwinPairs;
    pair.points_a_px = unflattenPoints(truth.points_a);
    pair.points_b_px = unflattenPoints(truth.points_b);
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

// The annotation file's pairs whose stamps are frames of this recording (each pair is taken by
// the first bag that has one of its stamps). A pair with only one of its stamps here, or with a
// point outside the image, is reported and not scored.
std::vector<PairToScore> EvaluationRun::pairsFromAnnotations(const Recording& recording) {
  const AnnotationFile& file = *options_.annotations;
  std::vector<PairToScore> pairs;
  for (std::size_t p = 0; p < file.pairs.size(); ++p) {
    if (annotation_used_[p]) continue;
    const AnnotatedPair& annotated_pair = file.pairs[p];
    const bool has_a = recording.frame_of_stamp.count(annotated_pair.stamp_a_ns) > 0;
    const bool has_b = recording.frame_of_stamp.count(annotated_pair.stamp_b_ns) > 0;
    if (!has_a && !has_b) continue;  // another bag's pair
    annotation_used_[p] = true;
    const std::string where = file.path + ":" + std::to_string(annotated_pair.lines.front()) + ": ";
    if (!has_a || !has_b) {
      report_.errors.push_back(where +
                               (has_a ? "stamp_b " + formatStampNs(annotated_pair.stamp_b_ns)
                                      : "stamp_a " + formatStampNs(annotated_pair.stamp_a_ns)) +
                               " is not a frame of " + recording.path + " (the other stamp is)");
      ++pairs_done_;
      continue;
    }
    if (!annotatedPointsInside(annotated_pair, recording)) {
      ++pairs_done_;
      continue;
    }
    PairToScore pair;
    pair.stamp_a_ns = annotated_pair.stamp_a_ns;
    pair.stamp_b_ns = annotated_pair.stamp_b_ns;
    pair.category = annotated_pair.category;
    pair.scope = options_.annotated_scope;
    pair.points_a_px = annotated_pair.points_a_px;
    pair.points_b_px = annotated_pair.points_b_px;
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

// False, with the first offending point reported, when a point of the pair is outside the image.
bool EvaluationRun::annotatedPointsInside(const AnnotatedPair& pair, const Recording& recording) {
  const CameraModel& camera = *recording.sequence.camera;
  for (std::size_t k = 0; k < pair.points_a_px.size(); ++k) {
    for (const Eigen::Vector2d& p_px : {pair.points_a_px[k], pair.points_b_px[k]}) {
      if (p_px.x() < -0.5 || p_px.y() < -0.5 || p_px.x() > camera.width() - 0.5 ||
          p_px.y() > camera.height() - 0.5) {
        report_.errors.push_back(options_.annotations->path + ":" + std::to_string(pair.lines[k]) + ": point (" +
                                 std::to_string(p_px.x()) + ", " + std::to_string(p_px.y()) + ") is outside the " +
                                 std::to_string(camera.width()) + "x" + std::to_string(camera.height()) +
                                 " image of " + recording.path + "; pair not scored");
        return false;
      }
    }
  }
  return true;
}

// Ghost images: the middle pair of each category of this recording (benchmark pairs only; the
// twins' only row is the gyro's), while the category needs samples.
void EvaluationRun::chooseGhostPairs(std::vector<PairToScore>& pairs) {
  std::map<std::string, std::vector<std::size_t>> of_category;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    if (pairs[p].scope & kBenchmarkPairs) of_category[pairs[p].category].push_back(p);
  }
  for (const auto& [category, members] : of_category) {
    if (ghost_samples_[category] >= options_.ghost_pairs_per_category) continue;
    pairs[members[members.size() / 2]].ghost = true;
    ++ghost_samples_[category];
  }
}

void EvaluationRun::scoreRecording(Recording& recording, RecordingOutcome& result) {
  describeRecording(recording, result);
  std::vector<PairToScore> pairs = annotated_ ? pairsFromAnnotations(recording) : pairsFromTruth(recording);
  if (options_.max_pairs_per_bag > 0 && pairs.size() > options_.max_pairs_per_bag) {
    pairs.resize(options_.max_pairs_per_bag);
  }
  chooseGhostPairs(pairs);
  for (std::size_t p = 0; p < pairs.size(); ++p) scorePair(recording, p, pairs[p], result);
}

// The pair's inputs as the nodelets would have them (the gyro flow nodelet's homographies and
// grid flow, the lens log's homographies), then every method whose scope holds the pair.
void EvaluationRun::scorePair(const Recording& recording, std::size_t p, const PairToScore& pair,
                              RecordingOutcome& result) {
  const BagSequence& sequence = recording.sequence;
  const CameraModel& camera = *sequence.camera;
  if (progress_) progress_->update(++pairs_done_);
  auto skip = [&](const std::string& reason) {
    ++result.pairs_skipped;
    ++result.skip_reasons[reason];
  };
  const auto frame_a = recording.frame_of_stamp.find(pair.stamp_a_ns);
  const auto frame_b = recording.frame_of_stamp.find(pair.stamp_b_ns);
  if (frame_a == recording.frame_of_stamp.end() || frame_b == recording.frame_of_stamp.end()) {
    skip("truth stamps are not frames of the bag");
    return;
  }
  if (pair.points_a_px.empty() || pair.points_a_px.size() != pair.points_b_px.size()) {
    skip("no annotated point");
    return;
  }
  const double stamp_a_s = sequence.secondsSinceBase(ros::Time().fromNSec(pair.stamp_a_ns));
  const double stamp_b_s = sequence.secondsSinceBase(ros::Time().fromNSec(pair.stamp_b_ns));
  // The gyro flow nodelet's computation for this pair.
  const RollingShutterHomographies gyro = computeRollingShutterHomographies(
      recording.imu, options_.gyro.integration, recording.rolling_shutter, camera.K(), stamp_a_s, stamp_b_s);
  if (!gyro.ok()) {
    skip(std::string("gyro: ") + toString(gyro.status));
    return;
  }
  const FramePairContext context =
      pairContext(recording, pair, recording.frames[frame_a->second], recording.frames[frame_b->second], gyro,
                  stamp_a_s, stamp_b_s);
  const double identity_px =
      geometryDistance(pair.points_a_px, pair.points_b_px, {Eigen::Matrix3d::Identity()}, camera.height());

  GhostSample ghost;
  if (pair.ghost) {
    ghost.category = pair.category;
    ghost.label = fileName(recording.path) + ", pair " + std::to_string(p) + " (" + formatStampNs(pair.stamp_a_ns) +
                  " -> " + formatStampNs(pair.stamp_b_ns) + ")" +
                  (options_.ghost_zoom > 1 ? ", centre " + std::to_string(options_.ghost_zoom) + "x" : "");
  }
  for (AlignmentMethod& method : methods_) {
    if ((method.scope & pair.scope) == 0) continue;
    scoreMethod(method, context, pair, identity_px, pair.ghost ? &ghost : nullptr);
  }
  if (pair.ghost) report_.ghosts.push_back(std::move(ghost));
  ++result.pairs_scored;
}

// One method on one pair: its time, its distance capped at identity (identity where it fails or
// throws, with the reason counted) and, for a ghost pair, its panel.
void EvaluationRun::scoreMethod(AlignmentMethod& method, const FramePairContext& context, const PairToScore& pair,
                                double identity_px, GhostSample* ghost) {
  AlignmentEstimate estimate;
  PairScore score;
  score.recording = static_cast<std::size_t>(context.recording_id);
  score.stamp_a_ns = pair.stamp_a_ns;
  score.stamp_b_ns = pair.stamp_b_ns;
  score.category = pair.category;
  score.method = method.name;
  score.identity_px = identity_px;
  score.distance_px = std::nan("");
  const Clock::time_point estimating = Clock::now();
  try {
    estimate = method.estimate(context);
    report_.method_s[method.name] += secondsSince(estimating);
    if (estimate.ok()) {
      score.distance_px = estimateDistance(estimate, context);
      if (!std::isfinite(score.distance_px)) score.failure = "non-finite motion";
    } else {
      score.failure = estimate.failure_reason.empty() ? "no estimate" : estimate.failure_reason;
    }
  } catch (const std::exception& e) {
    report_.method_s[method.name] += secondsSince(estimating);
    score.failure = std::string("error: ") + e.what();
  }
  if (!score.failure.empty()) {
    estimate = AlignmentEstimate::failed(score.failure);
    report_.table.addFailure(method.name, pair.category, identity_px);
    ++report_.failure_reasons[method.name][score.failure];
    score.scored_px = identity_px;
  } else {
    score.scored_px = report_.table.addCapped(method.name, pair.category, score.distance_px, identity_px);
  }
  report_.pairs.push_back(score);
  if (!ghost) return;
  GhostPanel panel;
  panel.method = method.name;
  panel.distance_px = score.scored_px;
  panel.failed = !estimate.ok();
  panel.capped = estimate.ok() && score.distance_px > identity_px;
  try {
    panel.ghost_rgb = magnifyCentre(
        ghostOverlay(context.rgb_a, warpFrameBOntoA(context.rgb_b, estimateCameraFlow(estimate, *context.camera))),
        options_.ghost_zoom);
    ghost->panels.push_back(std::move(panel));
  } catch (const std::exception&) {
    // A motion that cannot be drawn was already scored (as a failure); the panel stays blank.
  }
}

void EvaluationRun::reportUnmatchedAnnotations() {
  if (!annotated_) return;
  for (std::size_t p = 0; p < annotation_used_.size(); ++p) {
    if (annotation_used_[p]) continue;
    const AnnotatedPair& pair = options_.annotations->pairs[p];
    report_.errors.push_back(options_.annotations->path + ":" + std::to_string(pair.lines.front()) + ": pair " +
                             formatStampNs(pair.stamp_a_ns) + " -> " + formatStampNs(pair.stamp_b_ns) +
                             " matches no frame of the bags given");
  }
}

// The progress bar to its end; categories in the paper's order, rows in the order added.
void EvaluationRun::finish() {
  if (progress_) {
    if (pairs_done_ < total_pairs_) progress_->update(total_pairs_);  // pairs no bag held
    if (progress_->drawing()) std::fprintf(stderr, "\n");
  }
  report_.table.orderCategories({"RE", "LT", "LL", "MF"});  // the paper's column order
  std::vector<std::string> method_order;
  for (const AlignmentMethod& method : methods_) {
    method_order.push_back(method.name);
    report_.method_scopes.emplace_back(method.name, method.scope);
  }
  report_.table.orderMethods(method_order);
  report_.elapsed_s = secondsSince(started_);
}

}  // namespace

EvaluationReport EvaluationRunner::run() { return EvaluationRun(options_, methods_).run(); }

}  // namespace deep_ois
