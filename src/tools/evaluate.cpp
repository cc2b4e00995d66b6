// Scores frame pairs with annotated correspondences (simulator bags) and prints the paper's table:
// mean geometry distance |p_a + flow(p_a) - p_b| per category and method, errors capped at the
// identity error of the pair, Avg = mean of the category means.
//
//   evaluate --bags a.bag [b.bag ...] [--gyro-config config/gyro_flow.yaml] [--out DIR]
//
// Rows today: identity; gyro on the non-OIS twin (bags whose truth says OIS off); gyro on the OIS
// camera, uncompensated. The gyro flow runs the nodelet's code with the nodelet's parameters.
#include <ros/package.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/evaluation_table.h"
#include "deep_ois/core/geometry_distance.h"
#include "deep_ois/core/rolling_shutter_homographies.h"
#include "deep_ois/ros/bag_sequence.h"
#include "deep_ois/ros/conversions.h"
#include "deep_ois/ros/gyro_flow_parameters.h"

namespace {

int usage(const std::string& problem) {
  std::fprintf(stderr,
               "evaluate: %s\nusage: evaluate --bags FILE.bag [FILE.bag ...] "
               "[--gyro-config config/gyro_flow.yaml] [--out DIR]\n",
               problem.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> bags;
  // The nodelet's own parameter file, wherever the package is (source checkout or install).
  std::string gyro_config = ros::package::getPath("deep_ois") + "/config/gyro_flow.yaml";
  std::string out_dir;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--bags") {
      while (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) bags.push_back(argv[++i]);
    } else if (flag == "--gyro-config" && i + 1 < argc) {
      gyro_config = argv[++i];
    } else if (flag == "--out" && i + 1 < argc) {
      out_dir = argv[++i];
    } else {
      return usage("unknown flag or missing value: " + flag);
    }
  }
  if (bags.empty()) return usage("--bags needs at least one bag");
  if (gyro_config == "/config/gyro_flow.yaml") {
    return usage("package deep_ois not found (source its setup.bash), so pass --gyro-config");
  }

  const std::string kIdentity = "identity", kGyroTwin = "gyro, non-OIS camera (twin)",
                    kGyroOis = "gyro, OIS camera (uncompensated)";
  deep_ois::EvaluationTable scores;
  int failures = 0;
  try {
    const deep_ois::GyroFlowParameters params =
        deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
    for (const std::string& path : bags) {
      try {
        const deep_ois::BagSequence bag = deep_ois::readBagSequence(path);
        if (bag.truths.empty()) throw std::runtime_error("no annotated frame pairs (/ground_truth/frame_pair)");
        deep_ois::RollingShutterConfig rs = params.rolling_shutter;
        if (params.rotation_from_tf) {
          if (!bag.imu_to_camera_rotation) throw std::runtime_error("no IMU -> camera transform in /tf_static");
          rs.imu_to_camera_rotation = *bag.imu_to_camera_rotation;
        }
        const deep_ois::ImuSampleBuffer buffer = bag.imuBuffer();
        int skipped = 0;
        for (const auto& truth : bag.truths) {
          const auto points_a = deep_ois::unflattenPoints(truth.points_a),
                     points_b = deep_ois::unflattenPoints(truth.points_b);
          if (points_a.empty()) continue;
          const int h = static_cast<int>(truth.image_height);
          const double identity = deep_ois::geometryDistance(points_a, points_b, {Eigen::Matrix3d::Identity()}, h);
          const auto gyro = deep_ois::computeRollingShutterHomographies(
              buffer, params.integration, rs, bag.camera->K(), bag.secondsSinceBase(truth.previous_stamp),
              bag.secondsSinceBase(truth.header.stamp));
          if (!gyro.ok()) {
            ++skipped;
            continue;
          }
          const double gyro_px = deep_ois::geometryDistance(points_a, points_b, gyro.homographies, h);
          scores.add(kIdentity, truth.category, identity);
          scores.add(truth.ois_enabled ? kGyroOis : kGyroTwin, truth.category,
                     deep_ois::capAtIdentity(gyro_px, identity));
        }
        std::fprintf(stderr, "evaluate: %s: %zu pairs%s\n", path.c_str(), bag.truths.size(),
                     skipped ? (", " + std::to_string(skipped) + " without IMU coverage skipped").c_str() : "");
      } catch (const std::exception& e) {
        // One bad bag must not lose the others' results.
        std::fprintf(stderr, "evaluate: %s: %s (skipped)\n", path.c_str(), e.what());
        ++failures;
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evaluate: %s\n", e.what());
    return 1;
  }
  if (scores.methods().empty()) {
    std::fprintf(stderr, "evaluate: no frame pair could be scored\n");
    return 1;
  }
  scores.orderCategories({"RE", "LT", "LL", "MF"});  // the paper's column order
  std::printf("%s", scores.markdown().c_str());
  if (!out_dir.empty()) {
    const std::string csv_path = out_dir + "/evaluation.csv";
    std::ofstream csv(csv_path);
    csv << scores.csv();
    if (!csv) {
      std::fprintf(stderr, "evaluate: cannot write %s\n", csv_path.c_str());
      return 1;
    }
  }
  return failures > 0 ? 3 : 0;
}
