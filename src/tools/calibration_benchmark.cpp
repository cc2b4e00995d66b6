// Runs the camera-IMU calibration over simulator bags whose truth is in their simulator config
// and prints the error table, bags with a fixed lens (non-OIS) and with OIS reported apart.
// Flags: --help.
//
// The manifest (scripts/make_calibration_bags.sh writes it) has one line per bag,
// "<bag> <config.yaml>", paths relative to the manifest's folder. Whether a bag has OIS is read
// from its ground truth; OIS bags are calibrated with the per-frame lens shift (calibrate --ois
// on), the others without. The bias truth is the config's gyro_initial_bias_vector_rad_s (the bias
// random walk moves it by ~1e-5 rad/s over a few seconds). --ois-rotation tf holds the rotation of
// OIS bags at their /tf_static (calibrate --ois on --rotation tf: the mount known from a
// recording with OIS off or from CAD), to show the timing alone.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/sim/simulator_config.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/tools/support/command_line.h"

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

struct Row {
  std::string bag;
  bool ois = false;
  bool estimated = false;  // the estimator ran (a refused result still has an estimate)
  bool ok = false;         // and accepted it
  std::string reason;
  double true_offset_ms = 0, offset_error_ms = 0, offset_sigma_ms = 0;
  double true_readout_ms = 0, readout_error_ms = 0, readout_sigma_ms = 0;
  int true_mount = -1, found_mount = -1;
  double rotation_error_deg = 0, rotation_sigma_deg = 0;
  // The rotation error about the camera x, y, z axes (the estimator's increment frame) and the
  // reported 1-sigma about each, for the coverage count.
  Eigen::Vector3d rotation_error_axes_deg = Eigen::Vector3d::Zero(), rotation_sigma_axes_deg = Eigen::Vector3d::Zero();
  double bias_error_mrad_s = 0;
  double median_residual_px = 0;
  double tracking_s = 0, estimation_s = 0;
};

double maxAbs(const std::vector<Row>& rows, double Row::*field) {
  double worst = 0.0;
  for (const Row& row : rows) worst = std::max(worst, std::abs(row.*field));
  return worst;
}

double rms(const std::vector<Row>& rows, double Row::*field) {
  double sum = 0.0;
  for (const Row& row : rows) sum += (row.*field) * (row.*field);
  return rows.empty() ? 0.0 : std::sqrt(sum / rows.size());
}

// Errors over every bag that produced an estimate (refused ones too: whether the refusal was
// right is part of the result), and how many were accepted.
void printSummary(const std::string& label, const std::vector<Row>& all) {
  if (all.empty()) return;
  std::vector<Row> rows;
  int accepted = 0, accepted_within = 0, within = 0, mounts = 0;
  double tracking = 0, estimation = 0;
  for (const Row& row : all) {
    tracking += row.tracking_s;
    estimation += row.estimation_s;
    if (!row.estimated) continue;
    rows.push_back(row);
    const bool in_target = std::abs(row.offset_error_ms) <= 0.5 &&
                           std::abs(row.readout_error_ms) <= 0.5 && row.rotation_error_deg <= 0.5;
    within += in_target;
    accepted += row.ok;
    accepted_within += row.ok && in_target;
    mounts += row.found_mount == row.true_mount;
  }
  std::printf(
      "| %s | %zu | %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2f | %d/%zu | %d/%zu | %d/%d "
      "| %.1f + %.1f |\n",
      label.c_str(), all.size(), accepted, rms(rows, &Row::offset_error_ms),
      maxAbs(rows, &Row::offset_error_ms), rms(rows, &Row::readout_error_ms),
      maxAbs(rows, &Row::readout_error_ms), rms(rows, &Row::rotation_error_deg),
      maxAbs(rows, &Row::rotation_error_deg), maxAbs(rows, &Row::bias_error_mrad_s), mounts,
      rows.size(), within, rows.size(), accepted_within, accepted,
      all.empty() ? 0.0 : tracking / all.size(), all.empty() ? 0.0 : estimation / all.size());
}

// How often the reported 1-sigma (and 2-sigma) covers the actual error, per quantity, over every
// bag with an estimate (refused ones included); the rotation counted per camera axis (3 per bag).
void printCoverage(const std::vector<Row>& rows) {
  int n = 0, offset1 = 0, offset2 = 0, readout1 = 0, readout2 = 0, axes = 0, rotation1 = 0, rotation2 = 0;
  for (const Row& row : rows) {
    if (!row.estimated) continue;
    ++n;
    offset1 += std::abs(row.offset_error_ms) <= row.offset_sigma_ms;
    offset2 += std::abs(row.offset_error_ms) <= 2.0 * row.offset_sigma_ms;
    readout1 += std::abs(row.readout_error_ms) <= row.readout_sigma_ms;
    readout2 += std::abs(row.readout_error_ms) <= 2.0 * row.readout_sigma_ms;
    for (int k = 0; k < 3; ++k) {
      ++axes;
      rotation1 += std::abs(row.rotation_error_axes_deg(k)) <= row.rotation_sigma_axes_deg(k);
      rotation2 += std::abs(row.rotation_error_axes_deg(k)) <= 2.0 * row.rotation_sigma_axes_deg(k);
    }
  }
  if (n == 0) return;
  std::printf("\ncoverage of the reported sigma (|error| <= 1 sigma, <= 2 sigma; a Gaussian gives 68 %%, 95 %%): "
              "offset %d/%d, %d/%d; readout %d/%d, %d/%d; rotation per axis %d/%d, %d/%d\n",
              offset1, n, offset2, n, readout1, n, readout2, n, rotation1, axes, rotation2, axes);
}

}  // namespace

constexpr char kDescription[] =
    "Runs the camera-IMU calibration over simulator bags whose truth is in their simulator config "
    "and prints the error table (time offset and readout in ms, rotation in degrees, bias in "
    "mrad/s), bags with a fixed lens (non-OIS) and with OIS reported apart. OIS bags are "
    "calibrated "
    "with the per-frame lens shift (calibrate --ois on), the others without. --ois-rotation tf "
    "holds the rotation of OIS bags at their /tf_static (the mount known from a recording with OIS "
    "off or from CAD), to show the timing alone.";
constexpr char kFooter[] =
    "The manifest (scripts/make_calibration_bags.sh writes it) has one line per bag,\n"
    "\"<bag> <config.yaml>\", paths relative to the manifest's folder.\n"
    "Exit status: 0 done, 1 failed, 2 usage.";

int main(int argc, char** argv) {
  std::string manifest_path, csv_path, ois_rotation = "estimate";
  deep_ois::ToolCommandLine command_line("calibration_benchmark", kDescription, kFooter);
  CLI::App& app = command_line.app();
  app.add_option("--manifest", manifest_path, "the bags and their configs")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("DIR/manifest.txt");
  app.add_option("--csv", csv_path, "also write one line per bag")->type_name("OUT.csv");
  app.add_option("--ois-rotation", ois_rotation,
                 "the rotation of OIS bags: estimated or held at /tf_static")
      ->check(deep_ois::oneOf({"tf", "estimate"}))
      ->capture_default_str()
      ->type_name("tf|estimate");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  const bool hold_ois_rotation = ois_rotation == "tf";
  std::ifstream manifest(manifest_path);
  if (!manifest) return command_line.usageError("cannot read " + manifest_path);
  const std::string folder = manifest_path.find('/') == std::string::npos
                                 ? "."
                                 : manifest_path.substr(0, manifest_path.find_last_of('/'));
  std::vector<std::pair<std::string, std::string>> entries;
  std::string line;
  while (std::getline(manifest, line)) {
    std::istringstream words(line);
    std::string bag, config;
    if (!(words >> bag >> config) || bag[0] == '#') continue;
    entries.emplace_back(folder + "/" + bag, folder + "/" + config);
  }
  if (entries.empty()) return command_line.usageError(manifest_path + " lists no bags");

  std::vector<Row> rows;
  std::printf(
      "| bag | OIS | offset ms | error ms (1-sigma) | readout ms | error ms (1-sigma) | mount | "
      "rotation error deg (1-sigma) | bias error mrad/s | residual px | result |\n"
      "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  for (const auto& [bag_path, config_path] : entries) {
    Row row;
    row.bag = bag_path.substr(bag_path.find_last_of('/') + 1);
    try {
      const deep_ois::sim::SimulatorConfig truth = deep_ois::sim::loadSimulatorConfig(config_path);
      const deep_ois::CalibrationBag bag =
          deep_ois::readCalibrationBag(bag_path, deep_ois::CalibrationBagOptions());
      row.ois = bag.simulated_ois_enabled.value_or(false);
      deep_ois::CalibrationOptions options;
      options.lens_shift = row.ois ? deep_ois::LensShiftHandling::kPerFrameShift
                                   : deep_ois::LensShiftHandling::kNone;
      if (row.ois && hold_ois_rotation) {
        if (!bag.tf_imu_to_camera_rotation)
          throw std::runtime_error(bag_path + ": no /tf_static rotation to hold");
        options.estimate_rotation = false;
        options.imu_to_camera_rotation = *bag.tf_imu_to_camera_rotation;
      }
      const deep_ois::CalibrationResult result = deep_ois::calibrateCameraImu(bag.data, options);
      const deep_ois::CameraImuCalibration& c = result.calibration;
      row.estimated = true;
      row.ok = result.ok();
      row.reason = result.reason();
      row.true_offset_ms = truth.imu.time_offset_s * 1e3;
      row.offset_error_ms = c.time_offset_s * 1e3 - row.true_offset_ms;
      row.offset_sigma_ms = c.time_offset_sigma_s * 1e3;
      row.true_readout_ms = truth.sensor.readout_time_s * 1e3;
      row.readout_error_ms = c.readout_time_s * 1e3 - row.true_readout_ms;
      row.readout_sigma_ms = c.readout_time_sigma_s * 1e3;
      row.true_mount = deep_ois::nearestSignedAxisPermutation(truth.imu.imu_to_camera_rotation);
      row.found_mount = deep_ois::nearestSignedAxisPermutation(c.imu_to_camera_rotation);
      row.rotation_error_deg = deep_ois::rotationAngleBetween(c.imu_to_camera_rotation,
                                                              truth.imu.imu_to_camera_rotation) *
                               kRadToDeg;
      row.rotation_sigma_deg = c.rotation_sigma_rad.maxCoeff() * kRadToDeg;
      row.rotation_error_axes_deg =
          deep_ois::logSO3(c.imu_to_camera_rotation * truth.imu.imu_to_camera_rotation.transpose()) * kRadToDeg;
      row.rotation_sigma_axes_deg = c.rotation_sigma_rad * kRadToDeg;
      const Eigen::Vector3d true_bias = truth.imu.gyro_initial_bias_vector_rad_s.value_or(Eigen::Vector3d::Zero());
      row.bias_error_mrad_s = (c.gyro_bias_rad_s - true_bias).norm() * 1e3;
      row.median_residual_px = result.median_residual_px;
      row.tracking_s = bag.tracking_seconds;
      row.estimation_s = result.seconds;
    } catch (const std::exception& e) {
      row.reason = e.what();
    }
    std::printf(
        "| %s | %s | %+.2f | %+.3f (%.3f) | %.2f | %+.3f (%.3f) | %d%s | %.3f (%.3f) | %.3f | %.3f "
        "| %s |\n",
        row.bag.c_str(), row.ois ? "on" : "off", row.true_offset_ms, row.offset_error_ms,
        row.offset_sigma_ms, row.true_readout_ms, row.readout_error_ms, row.readout_sigma_ms,
        row.true_mount, row.found_mount == row.true_mount ? "" : " (wrong)", row.rotation_error_deg,
        row.rotation_sigma_deg, row.bias_error_mrad_s, row.median_residual_px,
        row.ok ? "ok" : ("refused: " + row.reason).c_str());
    std::fflush(stdout);
    rows.push_back(row);
  }

  std::vector<Row> fixed_lens, ois;
  for (const Row& row : rows) (row.ois ? ois : fixed_lens).push_back(row);
  std::printf(
      "\n| bags | n | accepted | offset RMS ms | offset max ms | readout RMS ms | readout max ms | "
      "rotation RMS deg | rotation max deg | bias max mrad/s | mount right | within 0.5 ms / 0.5 "
      "ms / 0.5 deg | accepted and within | s per bag (KLT + estimation) |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  printSummary("non-OIS", fixed_lens);
  printSummary("OIS", ois);
  printCoverage(rows);

  if (!csv_path.empty()) {
    std::ofstream csv(csv_path);
    csv << "bag,ois,ok,true_offset_ms,offset_error_ms,offset_sigma_ms,true_readout_ms,readout_"
           "error_ms,"
           "readout_sigma_ms,true_mount,found_mount,rotation_error_deg,rotation_sigma_deg,bias_"
           "error_mrad_s,"
           "median_residual_px,tracking_s,estimation_s\n";
    for (const Row& r : rows) {
      csv << r.bag << "," << r.ois << "," << r.ok << "," << r.true_offset_ms << ","
          << r.offset_error_ms << "," << r.offset_sigma_ms << "," << r.true_readout_ms << ","
          << r.readout_error_ms << "," << r.readout_sigma_ms << "," << r.true_mount << ","
          << r.found_mount << "," << r.rotation_error_deg << "," << r.rotation_sigma_deg << ","
          << r.bias_error_mrad_s << "," << r.median_residual_px << "," << r.tracking_s << ","
          << r.estimation_s << "\n";
    }
    if (!csv) std::fprintf(stderr, "calibration_benchmark: cannot write %s\n", csv_path.c_str());
  }
  const bool all_estimated =
      std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.estimated; });
  return all_estimated ? 0 : 1;
}
