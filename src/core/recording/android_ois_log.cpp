#include "deep_ois/core/recording/android_ois_log.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

std::string findOne(const std::string& folder, const std::string& prefix) {
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) == 0 && entry.path().extension() == ".txt") found.push_back(entry.path().string());
  }
  if (found.size() != 1)
    throw std::runtime_error(folder + ": expected exactly one " + prefix + "*.txt (found " +
                             std::to_string(found.size()) + ")");
  return found.front();
}

std::vector<std::vector<double>> readRows(const std::string& path, std::size_t columns) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::vector<std::vector<double>> rows;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream fields(line);
    std::vector<double> row;
    double value = 0.0;
    while (fields >> value) row.push_back(value);
    if (row.size() < columns || !std::all_of(row.begin(), row.end(), [](double v) { return std::isfinite(v); }))
      throw std::runtime_error(path + ":" + std::to_string(number) + ": expected at least " +
                               std::to_string(columns) + " finite numbers");
    rows.push_back(row);
  }
  if (rows.empty()) throw std::runtime_error(path + ": no rows");
  return rows;
}

double readFov(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::smatch match;
  if (!std::regex_search(text, match, std::regex("\"fov\"\\s*:\\s*([0-9.eE+-]+)")))
    throw std::runtime_error(path + ": no \"fov\" field");
  const double fov = std::stod(match[1].str());
  if (!(fov > 0.0)) throw std::runtime_error(path + ": \"fov\" must be positive");
  return fov;
}

}  // namespace

AndroidOisLog readAndroidOisLog(const std::string& folder, const AndroidOisLogOptions& options) {
  if (options.gyro_time_column != 1 && options.gyro_time_column != 5)
    throw std::invalid_argument("gyro_time_column: must be 1 or 5");
  if (!(options.image_width_px > 0.0) || !(options.active_array_width_px > 0.0))
    throw std::invalid_argument("image_width_px and active_array_width_px must be positive");
  AndroidOisLog log;
  log.focal_px = options.image_width_px / readFov(folder + "/calib.txt");
  // Gyro rows: t_us, wx, wy, wz, t2_us, frame_id.
  for (const auto& row : readRows(findOne(folder, "gyro_log_"), 5)) {
    CameraRateSample sample;
    sample.stamp_s = row[static_cast<std::size_t>(options.gyro_time_column - 1)] * 1e-6;
    sample.rate_rad_s = Eigen::Vector3d(row[1], row[2], row[3]);
    if (!log.rates.empty() && !(sample.stamp_s > log.rates.back().stamp_s)) {
      ++log.gyro_rows_dropped;
      continue;
    }
    log.rates.push_back(sample);
  }
  // OIS rows: frame_id, x, y (active-array pixels), t_ns.
  const double scale = options.image_width_px / options.active_array_width_px;
  std::vector<LoggedLensSample> lens;
  for (const auto& row : readRows(findOne(folder, "ois_log_"), 4)) {
    LoggedLensSample sample;
    sample.stamp_s = row[3] * 1e-9;
    sample.shift_px = scale * Eigen::Vector2d(row[1], row[2]);
    if (!lens.empty() && sample.stamp_s < lens.back().stamp_s) ++log.lens_out_of_order;
    lens.push_back(sample);
  }
  log.lens_rows = lens.size();
  std::stable_sort(lens.begin(), lens.end(),
                   [](const LoggedLensSample& a, const LoggedLensSample& b) { return a.stamp_s < b.stamp_s; });
  for (const LoggedLensSample& sample : lens) {
    if (!log.lens.empty() && sample.stamp_s - log.lens.back().stamp_s < options.duplicate_within_s) {
      ++log.lens_repeats_dropped;
      continue;
    }
    log.lens.push_back(sample);
  }
  return log;
}

}  // namespace deep_ois
