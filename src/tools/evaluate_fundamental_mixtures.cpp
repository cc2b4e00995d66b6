// Scores the Fundamental Mixtures ground truth against the simulator's exact truth, next to the
// paper's ablation (one global fundamental matrix), per category:
//   - rotation error: per frame pair, the mean over the N row patches of the angle between the
//     estimated rotation R_i and the true camera rotation of that patch (FramePairTruth.rotations,
//     timed at the patch's middle row); the global variant's one rotation is compared with every
//     patch's. Median over the pairs of a category, degrees. Only on non-OIS bags: with OIS on, the
//     image motion K(t_b) R K(t_a)^-1 includes the lens shift, so no estimate from the images is a
//     pure camera rotation there.
//   - geometry distance (the paper's metric, as evaluate): the per-patch rotation-only homographies
//     applied to the annotated points of frame a, |H_i p_a - p_b| averaged over a pair's points,
//     then over the pairs of a category (capped at the identity error), pixels. On OIS and non-OIS
//     bags, with the true rotation-only motion of the camera as the floor a rotation-only model
//     can reach (the rest is translation parallax).
// Both methods are scored on the pairs that both accepted; the counts table says how many that is.
// Flags: --help.
//
// The tracker and solver run with the offline job's defaults; the flags override solver options
// (for the study behind the defaults; --paper-selection keeps the F rotations whenever F can be
// decomposed, as the paper does). --out writes one CSV line per pair and method.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/evaluation/results_table.h"
#include "deep_ois/core/ground_truth/fundamental_mixtures.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/vision/feature_tracker.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
const std::vector<std::string> kPaperCategories = {"RE", "LT", "LL", "MF"};
const std::string kMixtures = "Fundamental Mixtures", kGlobal = "global F";

// Mean over the patches of the angle between estimated and true rotations, degrees.
double meanPatchRotationErrorDeg(const std::vector<Eigen::Matrix3d>& estimated,
                                 const std::vector<Eigen::Matrix3d>& truth) {
  double sum = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    sum += deep_ois::logSO3(estimated[i].transpose() * truth[i]).norm() * kRadToDeg;
  }
  return sum / static_cast<double>(truth.size());
}

// Per method and category, the values of every pair; printed as medians (EvaluationTable holds
// only sums, for its means).
class MedianTable {
 public:
  void add(const std::string& method, const std::string& category, double value) {
    if (std::find(methods_.begin(), methods_.end(), method) == methods_.end())
      methods_.push_back(method);
    values_[{method, category}].push_back(value);
  }
  std::string markdown(const std::vector<std::string>& categories) const {
    std::ostringstream out;
    out << std::fixed << std::setprecision(3) << "| method |";
    for (const auto& category : categories) out << " " << category << " |";
    out << "\n|---|";
    for (std::size_t i = 0; i < categories.size(); ++i) out << "---:|";
    out << "\n";
    for (const auto& method : methods_) {
      out << "| " << method << " |";
      for (const auto& category : categories) {
        const auto it = values_.find({method, category});
        if (it == values_.end()) {
          out << " - |";
        } else {
          out << " " << (it->second.empty() ? std::nan("") : deep_ois::median(it->second)) << " |";
        }
      }
      out << "\n";
    }
    return out.str();
  }

 private:
  std::vector<std::string> methods_;
  std::map<std::pair<std::string, std::string>, std::vector<double>> values_;
};

// How often each method answered, and with which model, per category and OIS state.
struct Counts {
  int pairs = 0;
  int scored = 0;                                            // both methods accepted
  std::map<std::string, std::map<std::string, int>> models;  // method -> model -> pairs
};

std::string twinLabel(bool ois) { return ois ? "OIS" : "non-OIS"; }

}  // namespace

constexpr char kDescription[] =
    "Scores the Fundamental Mixtures ground truth against the simulator's exact truth, next to the "
    "paper's ablation (one global fundamental matrix), per category: the rotation error (median "
    "over "
    "pairs of the mean over row patches of the angle to the true patch rotation, degrees; non-OIS "
    "bags only) and the geometry distance of the rotation-only homographies on the annotated "
    "points "
    "(pixels, capped at identity; with the true rotation-only motion as the floor). Both methods "
    "are "
    "scored on the pairs that both accepted. The tracker and solver run with the offline job's "
    "defaults; the flags override solver options (for the study behind the defaults).";

int main(int argc, char** argv) {
  std::vector<std::string> bags;
  std::string out_dir;
  deep_ois::FundamentalMixturesOptions solver;
  bool unit_norm = false, paper_selection = false;
  deep_ois::ToolCommandLine command_line("evaluate_fundamental_mixtures", kDescription,
                                         "Exit status: 0 done, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--bags", bags, "simulator bags")->required()->type_name("FILE.bag");
  app.add_option("--out", out_dir,
                 "write fundamental_mixtures_pairs.csv (one line per pair and method) here")
      ->type_name("DIR");
  command_line
      .addNumber("--sigma", solver.weight_sigma_fraction,
                 "Gaussian weight sigma of the patch mixture, fraction of the image height")
      ->type_name("FRACTION");
  command_line
      .addNumber("--lambda", solver.smoothness_lambda,
                 "weight of a smoothness tie row relative to a data row")
      ->type_name("L");
  app.add_flag("--unit-norm", unit_norm,
               "the paper's literal ||f|| = 1 (well posed only with a sigma of several percent of "
               "the height)");
  command_line
      .addNumber("--rotation-tie", solver.rotation_tie_lambda,
                 "weight tying neighbouring patch rotations (0: none)")
      ->type_name("L");
  app.add_flag("--paper-selection", paper_selection,
               "keep the F rotations whenever F can be decomposed, as the paper does");
  command_line
      .addNumber("--max-parallax-share", solver.max_parallax_share,
                 "share of F inliers the rotation-only fit may reject before F is used")
      ->type_name("S");
  command_line
      .addNumber("--inlier-threshold", solver.inlier_threshold_px,
                 "inlier threshold of the refined per-patch models, pixels")
      ->type_name("PX");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (unit_norm) solver.scale_gauge = deep_ois::MixtureScaleGauge::kUnitNorm;
  if (paper_selection) solver.model_selection = deep_ois::ModelSelection::kFundamental;
  const std::string solver_problem = solver.validate();
  if (!solver_problem.empty()) return command_line.usageError(solver_problem);

  std::ofstream csv;
  if (!out_dir.empty()) {
    csv.open(out_dir + "/fundamental_mixtures_pairs.csv");
    if (!csv) {
      std::fprintf(
          stderr, "evaluate_fundamental_mixtures: cannot write %s/fundamental_mixtures_pairs.csv\n",
          out_dir.c_str());
      return 1;
    }
    csv << "bag,stamp,category,ois,method,accepted,model,rotation_error_deg,geometry_distance_px\n";
  }

  const deep_ois::FeatureTracker tracker;  // the offline job's defaults
  MedianTable rotation_error;
  std::map<bool, deep_ois::EvaluationTable> distance;  // by OIS on/off
  std::map<std::pair<bool, std::string>, Counts> counts;
  int failures = 0;
  for (const std::string& path : bags) {
    try {
      const deep_ois::BagSequence bag = deep_ois::readBagSequence(path);
      if (bag.truths.empty())
        throw std::runtime_error("no annotated frame pairs (/ground_truth/frame_pair)");
      std::map<ros::Time, const deep_ois::FramePairTruth*> truth_ending_at;
      for (const auto& truth : bag.truths) truth_ending_at[truth.header.stamp] = &truth;
      const deep_ois::CameraModel& camera = *bag.camera;

      deep_ois::BagFrameReader reader(path, deep_ois::BagSequenceTopics().image);
      deep_ois::BagFrame previous, current;
      int scored = 0;
      if (!reader.next(previous)) continue;
      for (; reader.next(current); std::swap(previous, current)) {
        const auto found = truth_ending_at.find(current.stamp);
        if (found == truth_ending_at.end()) continue;
        const deep_ois::FramePairTruth& truth = *found->second;
        if (truth.previous_stamp != previous.stamp) continue;  // a frame is missing in between
        const auto points_a = deep_ois::unflattenPoints(truth.points_a),
                   points_b = deep_ois::unflattenPoints(truth.points_b);
        const int h = static_cast<int>(truth.image_height);
        Counts& count = counts[{truth.ois_enabled, truth.category}];
        ++count.pairs;

        solver.patch_count = static_cast<int>(truth.patch_count);  // compare patch by patch
        const std::vector<deep_ois::FeatureMatch> matches =
            tracker.match(previous.gray, current.gray);
        const std::map<std::string, deep_ois::FundamentalMixturesResult> results = {
            {kMixtures, deep_ois::estimateFundamentalMixtures(matches, camera, solver)},
            {kGlobal, deep_ois::estimateGlobalFundamental(matches, camera, solver)}};
        bool all_ok = true;
        for (const auto& [method, result] : results) {
          ++count.models[method][result.ok() ? deep_ois::toString(result.model)
                                             : deep_ois::toString(result.status)];
          all_ok = all_ok && result.ok();
        }
        if (csv.is_open()) {
          for (const auto& [method, result] : results) {
            csv << path << "," << current.stamp << "," << truth.category << ","
                << static_cast<int>(truth.ois_enabled) << ",\"" << method << "\"," << result.ok()
                << ","
                << (result.ok() ? deep_ois::toString(result.model)
                                : deep_ois::toString(result.status))
                << ",";
            if (result.ok() && !truth.ois_enabled) {
              csv << meanPatchRotationErrorDeg(result.rotations,
                                               deep_ois::unflattenMatrices(truth.rotations));
            }
            csv << ",";
            if (result.ok() && !points_a.empty()) {
              csv << deep_ois::geometryDistance(points_a, points_b, result.homographies, h);
            }
            csv << "\n";
          }
        }
        if (!all_ok) continue;
        ++count.scored;
        ++scored;

        if (!truth.ois_enabled) {
          const auto true_rotations = deep_ois::unflattenMatrices(truth.rotations);
          for (const auto& [method, result] : results) {
            rotation_error.add(method, truth.category,
                               meanPatchRotationErrorDeg(result.rotations, true_rotations));
          }
        }
        if (points_a.empty()) continue;
        const double identity =
            deep_ois::geometryDistance(points_a, points_b, {Eigen::Matrix3d::Identity()}, h);
        const auto true_motion = deep_ois::unflattenMatrices(
            truth.ois_enabled ? truth.homographies_with_ois : truth.homographies_without_ois);
        deep_ois::EvaluationTable& table = distance[truth.ois_enabled];
        table.add("identity", truth.category, identity);
        table.add("true rotation (floor)", truth.category,
                  deep_ois::capAtIdentity(
                      deep_ois::geometryDistance(points_a, points_b, true_motion, h), identity));
        for (const auto& [method, result] : results) {
          table.add(method, truth.category,
                    deep_ois::capAtIdentity(
                        deep_ois::geometryDistance(points_a, points_b, result.homographies, h),
                        identity));
        }
      }
      std::fprintf(stderr, "evaluate_fundamental_mixtures: %s: %zu frames, %d pairs scored\n",
                   path.c_str(), reader.framesRead(), scored);
    } catch (const std::exception& e) {
      // One bad bag must not lose the others' results; bag readers name the file.
      std::fprintf(stderr, "evaluate_fundamental_mixtures: %s (skipped)\n", e.what());
      ++failures;
    }
  }
  if (counts.empty()) {
    std::fprintf(stderr, "evaluate_fundamental_mixtures: no frame pair could be scored\n");
    return 1;
  }

  std::printf(
      "Median over frame pairs of the mean patch rotation error against the true rotations, "
      "degrees (non-OIS bags)\n\n%s\n",
      rotation_error.markdown(kPaperCategories).c_str());
  for (auto& [ois, table] : distance) {
    table.orderCategories(kPaperCategories);
    std::printf(
        "Geometry distance of the rotation-only homographies on the annotated points, pixels "
        "(%s bags; true rotation = %s)\n\n%s\n",
        twinLabel(ois).c_str(), ois ? "K(t_b) R K(t_a)^-1 with the lens shift" : "K R K^-1",
        table.markdown().c_str());
  }
  std::printf("Pairs: scored (both accepted) / total; models chosen\n\n");
  std::printf("| bags | category | scored | %s | %s |\n|---|---|---:|---|---|\n", kMixtures.c_str(),
              kGlobal.c_str());
  for (const bool ois : {false, true}) {
    for (const std::string& category : kPaperCategories) {
      const auto it = counts.find({ois, category});
      if (it == counts.end()) continue;
      const Counts& count = it->second;
      std::printf("| %s | %s | %d / %d |", twinLabel(ois).c_str(), category.c_str(), count.scored,
                  count.pairs);
      for (const std::string& method : {kMixtures, kGlobal}) {
        std::string models;
        const auto m = count.models.find(method);
        if (m != count.models.end()) {
          for (const auto& [model, pairs] : m->second)
            models += (models.empty() ? "" : ", ") + model + " " + std::to_string(pairs);
        }
        std::printf(" %s |", models.c_str());
      }
      std::printf("\n");
    }
  }
  return failures > 0 ? 3 : 0;
}
