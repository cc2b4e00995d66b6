// Scores the gyro-anchored ground truth (core/ground_truth/lens_shift_ground_truth.h: the gyro's
// rotations plus a lens trajectory estimated from point tracks) against the simulator's exact
// truth, beside the paper's Fundamental Mixtures target, per category:
//   - lens motion error: per frame pair, the mean over the row patches of |(s_b - s_a) estimated -
//     (s_b - s_a) true|, the lens motion the pair's image motion holds (FramePairTruth.lens_shift_a
//     and _b), pixels; median and mean over the pairs of a category.
//   - geometry distance (the paper's metric, as evaluate): each target's homographies applied to the
//     annotated points of frame a, |H_i p_a - p_b| averaged over a pair's points, then over the
//     pairs; capped at the pair's identity error as in the paper, and uncapped. Beside them the
//     gyro alone (the network's input) and the simulator's true motion K(t_b) R K(t_a)^-1 (the floor;
//     what remains is translation parallax).
// Tracks: the offline job's tracker (uniform FAST corners, KLT). Gyro: the gyro flow nodelet's code
// with the given gyro flow parameters and the bag's IMU -> camera transform.
//
//   evaluate_lens_shift_ground_truth --bags a.bag [b.bag ...] [--gyro-config FILE] [--out FILE.csv]
#include <ros/package.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/evaluation/results_table.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"
#include "deep_ois/core/ground_truth/recording_lens_shift.h"
#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

const std::vector<std::string> kPaperCategories = {"RE", "LT", "LL", "MF"};
const std::string kIdentity = "identity", kGyro = "gyro alone (uncompensated)",
                  kMixtures = "Fundamental Mixtures (paper)",
                  kLensShift = "gyro-anchored lens shift", kTruth = "true motion (floor)";

// Per category, every pair's value; printed as median and mean.
class SampleTable {
 public:
  void add(const std::string& category, double value) { values_[category].push_back(value); }
  std::string markdown(const std::string& what) const {
    std::string out = "| " + what + " | pairs | median | mean |\n|---|---:|---:|---:|\n";
    for (const std::string& category : kPaperCategories) {
      const auto it = values_.find(category);
      if (it == values_.end()) continue;
      double sum = 0.0;
      for (double v : it->second) sum += v;
      char line[160];
      std::snprintf(line, sizeof(line), "| %s | %zu | %.3f | %.3f |\n", category.c_str(),
                    it->second.size(), deep_ois::median(it->second), sum / it->second.size());
      out += line;
    }
    return out;
  }

 private:
  std::map<std::string, std::vector<double>> values_;
};

struct PairRecord {
  int frame_a = 0;
  const deep_ois::FramePairTruth* truth = nullptr;
  std::vector<Eigen::Matrix3d> gyro_rotations;  // R_b_a per patch, camera frame
  std::vector<Eigen::Matrix3d> gyro_homographies;
  std::vector<Eigen::Matrix3d> mixtures_homographies;  // empty when the solver rejected the pair
};

}  // namespace

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "evaluate_lens_shift_ground_truth",
      "Scores the gyro-anchored lens-shift ground truth and Fundamental Mixtures against the "
      "simulator's truth, per category (capped and uncapped geometry distance, lens motion error).",
      "Exit status: 0 done, 1 nothing scored, 2 usage, 3 some bags failed.");
  CLI::App& app = command_line.app();
  std::vector<std::string> bags;
  const std::string package = ros::package::getPath("deep_ois");
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  std::string out_csv;
  app.add_option("--bags", bags, "simulator bags (with /ground_truth/frame_pair)")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--gyro-config", gyro_config, "gyro flow parameters (YAML)")
      ->capture_default_str()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  app.add_option("--out", out_csv, "one CSV line per pair and target")->type_name("FILE.csv");
  deep_ois::LensShiftOptions lens_options;
  command_line.addNumber("--huber", lens_options.huber_px, "Huber threshold of a track's residual, px");
  command_line.addNumber("--outlier", lens_options.outlier_px,
                         "tracks beyond this residual are outliers, px");
  command_line.addNumber("--random-walk", lens_options.lens_random_walk_px_per_sqrt_s,
                         "lens random-walk prior, px per sqrt(s)");
  command_line.addNumber("--centre-prior", lens_options.centre_prior_px, "lens centring prior, px");
  command_line.addNumber("--iterations", lens_options.iterations, "reweighting passes");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (gyro_config.empty()) {
    return command_line.usageError("--gyro-config: package deep_ois not found, so give the file");
  }

  deep_ois::GyroFlowParameters gyro_parameters;
  try {
    gyro_parameters = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evaluate_lens_shift_ground_truth: %s: %s\n", gyro_config.c_str(), e.what());
    return 2;
  }
  std::ofstream csv;
  if (!out_csv.empty()) {
    csv.open(out_csv);
    if (!csv) {
      std::fprintf(stderr, "evaluate_lens_shift_ground_truth: cannot write %s\n", out_csv.c_str());
      return 1;
    }
    csv << "bag,stamp,category,ois,target,distance_px,identity_px,lens_motion_error_px\n";
  }

  const deep_ois::FeatureTracker tracker;  // the offline job's defaults
  std::map<bool, deep_ois::EvaluationTable> capped, uncapped;  // by OIS on/off
  std::map<bool, SampleTable> lens_error;
  int failures = 0;
  for (const std::string& path : bags) {
    try {
      std::vector<deep_ois::BagFrame> frames;
      const deep_ois::BagSequence bag = deep_ois::readBagSequence(
          path, {}, deep_ois::BagReadFailure::kThrow, &frames);
      if (bag.truths.empty()) throw std::runtime_error(path + ": no /ground_truth/frame_pair");
      const deep_ois::CameraModel& camera = *bag.camera;
      deep_ois::RollingShutterConfig rs = gyro_parameters.rolling_shutter;
      if (gyro_parameters.rotation_from_tf) {
        if (!bag.imu_to_camera_rotation)
          throw std::runtime_error(path + ": no IMU -> camera transform in /tf_static");
        rs.imu_to_camera_rotation = *bag.imu_to_camera_rotation;
      }
      const deep_ois::ImuSampleBuffer imu = bag.imuBuffer();
      std::map<ros::Time, const deep_ois::FramePairTruth*> truth_ending_at;
      for (const auto& truth : bag.truths) truth_ending_at[truth.header.stamp] = &truth;

      deep_ois::FundamentalMixturesOptions solver;
      solver.patch_count = rs.patch_count;
      std::vector<double> stamps_s;
      std::vector<cv::Mat> gray;
      for (const auto& frame : frames) {
        stamps_s.push_back(bag.secondsSinceBase(frame.stamp));
        gray.push_back(frame.gray);
      }
      const deep_ois::RecordingLensShift estimate = deep_ois::estimateRecordingLensShift(
          camera, gray, stamps_s, imu, gyro_parameters.integration, rs, lens_options, tracker);
      const int gyro_gaps = static_cast<int>(estimate.pairs_without_gyro);
      const deep_ois::LensShiftTrajectory& trajectory = estimate.trajectory;
      // The annotated pairs among them, with the gyro's and Fundamental Mixtures' homographies.
      std::vector<PairRecord> records;
      for (std::size_t p = 0; p < estimate.pairs.size(); ++p) {
        const deep_ois::LensShiftPairObservation& observation = estimate.pairs[p];
        const auto truth = truth_ending_at.find(frames[observation.frame_b].stamp);
        if (truth == truth_ending_at.end() || truth->second->previous_stamp != frames[observation.frame_a].stamp) continue;
        PairRecord record;
        record.frame_a = observation.frame_a;
        record.truth = truth->second;
        record.gyro_rotations = observation.rotations;
        record.gyro_homographies = estimate.gyro_homographies[p];
        const deep_ois::FundamentalMixturesResult mixtures =
            deep_ois::estimateFundamentalMixtures(observation.matches, camera, solver);
        if (mixtures.ok()) record.mixtures_homographies = mixtures.homographies;
        records.push_back(std::move(record));
      }

      for (const PairRecord& record : records) {
        const deep_ois::FramePairTruth& truth = *record.truth;
        const auto points_a = deep_ois::unflattenPoints(truth.points_a);
        const auto points_b = deep_ois::unflattenPoints(truth.points_b);
        const auto& s_a = trajectory.shift_px[record.frame_a];
        const auto& s_b = trajectory.shift_px[record.frame_a + 1];
        const auto true_a = deep_ois::unflattenPoints(truth.lens_shift_a);
        const auto true_b = deep_ois::unflattenPoints(truth.lens_shift_b);
        double motion_error = 0.0;
        for (int i = 0; i < rs.patch_count; ++i)
          motion_error += ((s_b[i] - s_a[i]) - (true_b[i] - true_a[i])).norm();
        motion_error /= rs.patch_count;
        lens_error[truth.ois_enabled].add(truth.category, motion_error);
        if (points_a.empty()) continue;
        const double identity =
            deep_ois::geometryDistance(points_a, points_b, {Eigen::Matrix3d::Identity()}, camera);
        std::map<std::string, std::vector<Eigen::Matrix3d>> targets = {
            {kGyro, record.gyro_homographies},
            {kLensShift,
             deep_ois::lensShiftHomographies(camera.K(), record.gyro_rotations, s_a, s_b)},
            {kTruth, deep_ois::unflattenMatrices(truth.ois_enabled ? truth.homographies_with_ois
                                                                   : truth.homographies_without_ois)}};
        if (!record.mixtures_homographies.empty())
          targets[kMixtures] = record.mixtures_homographies;
        for (auto* table : {&capped[truth.ois_enabled], &uncapped[truth.ois_enabled]})
          table->add(kIdentity, truth.category, identity);
        for (const std::string& name : {kGyro, kMixtures, kLensShift, kTruth}) {
          const auto target = targets.find(name);
          if (target == targets.end()) {
            capped[truth.ois_enabled].addFailure(name, truth.category, identity);
            uncapped[truth.ois_enabled].addFailure(name, truth.category, identity);
            continue;
          }
          const double distance =
              deep_ois::geometryDistance(points_a, points_b, target->second, camera);
          capped[truth.ois_enabled].addCapped(name, truth.category, distance, identity);
          uncapped[truth.ois_enabled].add(name, truth.category, distance);
          if (csv.is_open()) {
            csv << path << "," << truth.header.stamp << "," << truth.category << ","
                << static_cast<int>(truth.ois_enabled) << ",\"" << name << "\"," << distance << ","
                << identity << "," << (name == kLensShift ? motion_error : std::nan("")) << "\n";
          }
        }
      }
      std::fprintf(stderr,
                   "evaluate_lens_shift_ground_truth: %s: %zu frames, %zu pairs scored, %d pairs "
                   "without gyro coverage\n",
                   path.c_str(), frames.size(), records.size(), gyro_gaps);
    } catch (const std::exception& e) {
      // One bad bag must not lose the others' results.
      std::fprintf(stderr, "evaluate_lens_shift_ground_truth: %s (skipped)\n", e.what());
      ++failures;
    }
  }
  if (capped.empty()) {
    std::fprintf(stderr, "evaluate_lens_shift_ground_truth: no frame pair could be scored\n");
    return 1;
  }
  for (const bool ois : {true, false}) {
    if (!capped.count(ois)) continue;
    const char* label = ois ? "OIS camera" : "non-OIS twin";
    for (auto* table : {&capped[ois], &uncapped[ois]}) {
      table->orderCategories(kPaperCategories);
      table->orderMethods({kIdentity, kGyro, kMixtures, kLensShift, kTruth});
    }
    std::printf("Geometry distance, %s, capped at identity (the paper's metric), pixels\n\n%s\n",
                label, capped[ois].markdown().c_str());
    std::printf("Geometry distance, %s, uncapped, pixels\n\n%s\n", label,
                uncapped[ois].markdown().c_str());
    std::printf("Lens motion error of the gyro-anchored estimate, %s, pixels\n\n%s\n", label,
                lens_error[ois].markdown("category").c_str());
  }
  return failures > 0 ? 3 : 0;
}
