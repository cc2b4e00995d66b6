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
#include <memory>
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
  // Per IMU axis, for the coverage count.
  Eigen::Vector3d bias_error_axes_mrad_s = Eigen::Vector3d::Zero(), bias_sigma_axes_mrad_s = Eigen::Vector3d::Zero();
  // The statistical part of each reported 1-sigma (CalibrationResult::statistical).
  double offset_statistical_ms = 0, readout_statistical_ms = 0;
  Eigen::Vector3d rotation_statistical_axes_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d bias_statistical_axes_mrad_s = Eigen::Vector3d::Zero();
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

// How often the reported 1-sigma (and 2-sigma) covers the actual error, and the median reported
// 1-sigma (how wide the interval is), per quantity, over every bag with an estimate (refused ones
// included) of one lens kind; the rotation and the bias counted per axis (3 per bag). A held
// quantity (sigma 0) is not counted.
void printCoverage(const std::string& label, const std::vector<Row>& rows) {
  struct Count {
    int n = 0, one = 0, two = 0;
    std::vector<double> sigmas;
    void add(double error, double sigma) {
      if (!(sigma > 0.0)) return;
      ++n;
      one += std::abs(error) <= sigma;
      two += std::abs(error) <= 2.0 * sigma;
      sigmas.push_back(sigma);
    }
    std::string text(const char* unit) const {
      if (n == 0) return "held";
      char buffer[160];
      std::snprintf(buffer, sizeof(buffer), "%d/%d (%.0f %%), %d/%d, median 1-sigma %.3f %s", one, n,
                    100.0 * one / n, two, n, deep_ois::median(sigmas), unit);
      return buffer;
    }
  } offset, readout, rotation, bias;
  int bags = 0, rotation_bags = 0;  // bags whose three rotation axes are all within 1 sigma
  for (const Row& row : rows) {
    if (!row.estimated) continue;
    if (row.rotation_sigma_axes_deg.minCoeff() > 0.0) {
      ++bags;
      rotation_bags += (row.rotation_error_axes_deg.cwiseAbs().array() <= row.rotation_sigma_axes_deg.array()).all();
    }
    offset.add(row.offset_error_ms, row.offset_sigma_ms);
    readout.add(row.readout_error_ms, row.readout_sigma_ms);
    for (int k = 0; k < 3; ++k) {
      rotation.add(row.rotation_error_axes_deg(k), row.rotation_sigma_axes_deg(k));
      bias.add(row.bias_error_axes_mrad_s(k), row.bias_sigma_axes_mrad_s(k));
    }
  }
  if (offset.n + readout.n + rotation.n + bias.n == 0) return;
  std::printf("coverage of the reported sigma, %s (|error| <= 1 sigma, <= 2 sigma; a Gaussian gives 68 %%, 95 %%):\n"
              "  offset %s\n  readout %s\n  rotation per axis %s; all three axes within 1 sigma: %d/%d bags\n"
              "  bias per axis %s\n",
              label.c_str(), offset.text("ms").c_str(), readout.text("ms").c_str(), rotation.text("deg").c_str(),
              rotation_bags, bags, bias.text("mrad/s").c_str());
}

void writeCsvHeader(std::ostream& csv) {
  csv << "bag,ois,ok,true_offset_ms,offset_error_ms,offset_sigma_ms,true_readout_ms,readout_error_ms,"
         "readout_sigma_ms,true_mount,found_mount,rotation_error_deg,rotation_sigma_deg,bias_error_mrad_s,"
         "median_residual_px,tracking_s,estimation_s,offset_statistical_ms,readout_statistical_ms";
  for (const char* quantity : {"rotation_error_deg", "rotation_sigma_deg", "rotation_statistical_deg",
                               "bias_error_mrad_s", "bias_sigma_mrad_s", "bias_statistical_mrad_s"}) {
    for (const char* axis : {"x", "y", "z"}) csv << "," << quantity << "_" << axis;
  }
  csv << "\n";
}

// One line per bag, written as soon as the bag is done (a long run keeps what it finished).
void writeCsvRow(std::ostream& csv, const Row& r) {
  csv << r.bag << "," << r.ois << "," << r.ok << "," << r.true_offset_ms << "," << r.offset_error_ms << ","
      << r.offset_sigma_ms << "," << r.true_readout_ms << "," << r.readout_error_ms << "," << r.readout_sigma_ms
      << "," << r.true_mount << "," << r.found_mount << "," << r.rotation_error_deg << "," << r.rotation_sigma_deg
      << "," << r.bias_error_mrad_s << "," << r.median_residual_px << "," << r.tracking_s << "," << r.estimation_s
      << "," << r.offset_statistical_ms << "," << r.readout_statistical_ms;
  for (const Eigen::Vector3d* values :
       {&r.rotation_error_axes_deg, &r.rotation_sigma_axes_deg, &r.rotation_statistical_axes_deg,
        &r.bias_error_axes_mrad_s, &r.bias_sigma_axes_mrad_s, &r.bias_statistical_axes_mrad_s}) {
    for (int k = 0; k < 3; ++k) csv << "," << (*values)(k);
  }
  csv << std::endl;
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

  std::unique_ptr<std::ofstream> csv;
  if (!csv_path.empty()) {
    csv = std::make_unique<std::ofstream>(csv_path);
    writeCsvHeader(*csv);
  }
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
      row.bias_error_axes_mrad_s = (c.gyro_bias_rad_s - true_bias) * 1e3;
      row.bias_sigma_axes_mrad_s = c.gyro_bias_sigma_rad_s * 1e3;
      row.offset_statistical_ms = result.statistical.time_offset_s * 1e3;
      row.readout_statistical_ms = result.statistical.readout_time_s * 1e3;
      row.rotation_statistical_axes_deg = result.statistical.rotation_rad * kRadToDeg;
      row.bias_statistical_axes_mrad_s = result.statistical.gyro_bias_rad_s * 1e3;
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
    if (csv) writeCsvRow(*csv, row);
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
  std::printf("\n");
  printCoverage("non-OIS", fixed_lens);
  printCoverage("OIS", ois);
  printCoverage("all", rows);

  if (csv && !*csv) std::fprintf(stderr, "calibration_benchmark: cannot write %s\n", csv_path.c_str());
  const bool all_estimated =
      std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.estimated; });
  return all_estimated ? 0 : 1;
}
