// Writes simulator configs with known camera-IMU calibrations, for the calibration benchmark
// (scripts/make_calibration_bags.sh runs simulate on each): time offsets spread over
// [-50, +50] ms and readout times over [0, 33] ms (stratified, so the ranges are covered), every
// one of the 24 signed axis permutations as the IMU mount (in shuffled order, then at random)
// turned by 1-5 degrees about a random axis, and a gyro bias of up to 0.01 rad/s per axis.
// Flags: --help.
//
// Writes DIR/cal_<i>.yaml (i = 00..count-1) and prints one line of truth per config. Same
// arguments, same files.
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/gyro/orientation_integrator.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

constexpr double kPi = 3.14159265358979323846;

// A permutation of 0..n-1 from the portable generator (Fisher-Yates).
std::vector<int> shuffled(int n, std::mt19937& rng) {
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (int i = n - 1; i > 0; --i) {
    const int j = std::min(static_cast<int>(deep_ois::uniform01(rng) * (i + 1)), i);
    std::swap(order[i], order[j]);
  }
  return order;
}

YAML::Node flowSequence(const double* values, int count) {
  YAML::Node node(YAML::NodeType::Sequence);
  for (int i = 0; i < count; ++i) node.push_back(values[i]);
  node.SetStyle(YAML::EmitterStyle::Flow);
  return node;
}

}  // namespace

constexpr char kDescription[] =
    "Writes simulator configs with known camera-IMU calibrations, for the calibration benchmark "
    "(scripts/make_calibration_bags.sh runs simulate on each): time offsets spread over [-50, +50] "
    "ms and readout times over [0, 33] ms (stratified, so the ranges are covered), every one of "
    "the "
    "24 signed axis permutations as the IMU mount (in shuffled order, then at random) turned by "
    "1-5 "
    "degrees about a random axis, and a gyro bias of up to 0.01 rad/s per axis. Writes "
    "DIR/cal_<i>.yaml (i = 00..count-1) and prints one line of truth per config. Same arguments, "
    "same files.";

int main(int argc, char** argv) {
  std::string base_path, out_dir;
  int count = 24;
  std::uint32_t seed = 1;
  deep_ois::ToolCommandLine command_line("make_calibration_configs", kDescription,
                                         "Exit status: 0 written, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  app.add_option("--base", base_path, "the simulator config the others start from")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.yaml");
  command_line.addNumber("--count", count, "configs to write, 1..1000")->check(CLI::Range(1, 1000));
  command_line.addNumber("--seed", seed, "seed of the calibrations, 0..4294967295");
  app.add_option("--out", out_dir, "folder of the configs")->required()->type_name("DIR");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    const deep_ois::sim::SimulatorConfig base = deep_ois::sim::loadSimulatorConfig(base_path);
    const double frame_period_s = 1.0 / base.sensor.frame_rate_hz;
    const double max_readout_s = std::min(0.033, frame_period_s);
    std::mt19937 rng = deep_ois::streamGenerator(static_cast<std::uint32_t>(seed), 0);
    const std::vector<int> offset_strata = shuffled(static_cast<int>(count), rng);
    const std::vector<int> readout_strata = shuffled(static_cast<int>(count), rng);
    const std::vector<int> mounts = shuffled(24, rng);
    std::printf("# config  time_offset_ms  readout_ms  mount  misalignment_deg  bias_rad_s\n");
    for (int i = 0; i < count; ++i) {
      const double offset_s = -0.05 + 0.1 * (offset_strata[i] + deep_ois::uniform01(rng)) / count;
      const double readout_s =
          max_readout_s * (readout_strata[i] + deep_ois::uniform01(rng)) / count;
      const int mount =
          i < 24 ? mounts[i] : std::min(static_cast<int>(deep_ois::uniform01(rng) * 24), 23);
      const Eigen::Vector3d axis = deep_ois::gaussian3(rng).normalized();
      const double angle_deg = deep_ois::uniform(rng, 1.0, 5.0);
      const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> R =
          deep_ois::expSO3(axis * angle_deg * kPi / 180.0) *
          deep_ois::signedAxisPermutations()[mount];
      Eigen::Vector3d bias;
      for (int k = 0; k < 3; ++k) bias(k) = deep_ois::uniform(rng, -0.01, 0.01);

      YAML::Node root = YAML::LoadFile(base_path);
      root["sensor"]["readout_time_s"] = readout_s;
      root["imu"]["time_offset_s"] = offset_s;
      root["imu"]["imu_to_camera_rotation"] = flowSequence(R.data(), 9);
      root["imu"]["gyro_initial_bias_vector_rad_s"] = flowSequence(bias.data(), 3);
      char name[32];
      std::snprintf(name, sizeof(name), "cal_%02d.yaml", i);
      const std::string path = out_dir + "/" + name;
      YAML::Emitter emitter;
      emitter.SetDoublePrecision(17);
      emitter << root;
      std::ofstream file(path);
      file << "# deep_ois calibration benchmark config " << name << ", from " << base_path
           << " (make_calibration_configs --seed " << seed
           << "): time offset, readout, IMU mount and gyro bias are the truth.\n"
           << emitter.c_str() << "\n";
      if (!file) throw std::runtime_error(path + ": cannot write");
      file.close();
      deep_ois::sim::loadSimulatorConfig(path);  // it must load: same validation as simulate
      std::printf("%s  %+8.3f  %7.3f  %2d  %.2f  [%+.5f %+.5f %+.5f]\n", name, offset_s * 1e3,
                  readout_s * 1e3, mount, angle_deg, bias(0), bias(1), bias(2));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_calibration_configs: %s\n", e.what());
    return 1;
  }
  return 0;
}
