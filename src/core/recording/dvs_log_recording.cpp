#include "deep_ois/core/recording/dvs_log_recording.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "deep_ois/core/recording/phone_recording.h"

namespace deep_ois {

namespace {

std::string findOne(const std::string& directory, const std::string& prefix) {
  namespace fs = std::filesystem;
  std::vector<std::string> found;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) == 0 && entry.path().extension() == ".txt") found.push_back(entry.path().string());
  }
  if (error) throw RecordingFormatError(directory, 0, "cannot list the folder: " + error.message());
  if (found.empty()) throw RecordingFormatError(directory, 0, "no " + prefix + "*.txt (a DVS log folder has frame_timestamps_*, gyro_log_* and ois_log_*)");
  if (found.size() > 1) throw RecordingFormatError(directory, 0, "several " + prefix + "*.txt: give one recording's folder");
  return found.front();
}

// Rows of whitespace-separated numbers with exactly `columns` fields; blank lines skipped.
template <typename Row>
void readRows(const std::string& path, std::size_t columns, const char* layout, Row row) {
  std::ifstream in(path);
  if (!in) throw RecordingFormatError(path, 0, "cannot open file for reading");
  std::string text;
  int line = 0;
  std::vector<double> values;
  while (std::getline(in, text)) {
    ++line;
    std::istringstream fields(text);
    values.clear();
    std::string field;
    while (fields >> field) {
      char* end = nullptr;
      const double value = std::strtod(field.c_str(), &end);
      if (end != field.c_str() + field.size() || !std::isfinite(value)) {
        throw RecordingFormatError(path, line, "field " + std::to_string(values.size() + 1) + " '" + field +
                                                   "' is not a number (expected " + layout + ")");
      }
      values.push_back(value);
    }
    if (values.empty()) continue;
    if (values.size() != columns) {
      throw RecordingFormatError(path, line, "expected " + std::to_string(columns) + " fields (" + layout +
                                                 "), got " + std::to_string(values.size()));
    }
    row(values, line);
  }
  if (in.bad()) throw RecordingFormatError(path, line + 1, "read error");
  if (line == 0) throw RecordingFormatError(path, 0, "empty file");
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

}  // namespace

DvsLogFiles dvsLogLayout(const std::string& directory) {
  if (!std::filesystem::is_directory(directory)) throw RecordingFormatError(directory, 0, "not a folder");
  DvsLogFiles files;
  files.frame_timestamps = findOne(directory, "frame_timestamps_");
  files.gyro_log = findOne(directory, "gyro_log_");
  files.ois_log = findOne(directory, "ois_log_");
  if (std::filesystem::exists(directory + "/calib.txt")) files.calib = directory + "/calib.txt";
  return files;
}

DvsLogRecording loadDvsLogRecording(const DvsLogFiles& files) {
  DvsLogRecording out;
  std::vector<double> readouts, exposures;
  int previous_line = 0;
  readRows(files.frame_timestamps, 7, "t_ns exposure_ns ISO readout_ns ois_t_ns zoom frame_id",
           [&](const std::vector<double>& v, int line) {
             const double t = v[0] * 1e-9;
             if (!out.frame_stamps_s.empty() && !(t > out.frame_stamps_s.back())) {
               throw RecordingFormatError(files.frame_timestamps, line,
                                          "frame stamp does not increase (previous on line " +
                                              std::to_string(previous_line) + ")");
             }
             out.frame_stamps_s.push_back(t);
             out.frame_lines.push_back(line);
             exposures.push_back(v[1] * 1e-9);
             readouts.push_back(v[3] * 1e-9);
             previous_line = line;
           });
  out.readout_s = median(readouts);
  out.exposure_s = median(exposures);
  for (double r : readouts) out.readout_rows_differing += std::abs(r - out.readout_s) > 1e-6;
  previous_line = 0;
  readRows(files.gyro_log, 6, "t_us wx wy wz t2_us frame_id", [&](const std::vector<double>& v, int line) {
    ImuSample sample;
    sample.stamp_s = v[0] * 1e-6;
    sample.angular_velocity_rad_s = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!out.gyro.empty() && !(sample.stamp_s > out.gyro.back().stamp_s)) {
      throw RecordingFormatError(files.gyro_log, line, "gyro stamp does not increase (previous on line " +
                                                           std::to_string(previous_line) + ")");
    }
    out.gyro.push_back(sample);
    previous_line = line;
  });
  readRows(files.ois_log, 4, "frame_id x y t_ns", [&](const std::vector<double>& v, int line) {
    LensShiftLogSample sample;
    sample.stamp_s = v[3] * 1e-9;
    sample.logged = Eigen::Vector2d(v[1], v[2]);
    out.ois.push_back(sample);
    out.ois_lines.push_back(line);
  });
  if (!files.calib.empty()) {
    std::ifstream in(files.calib);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::smatch match;
    if (!std::regex_search(text, match, std::regex("\"fov\"\\s*:\\s*([0-9.eE+-]+)"))) {
      throw RecordingFormatError(files.calib, 0, "no \"fov\" (sensor width / focal length)");
    }
    out.fov = std::stod(match[1]);
    if (!(out.fov > 0.1 && out.fov < 10.0)) throw RecordingFormatError(files.calib, 0, "fov " + match[1].str() + " is not plausible");
  }
  return out;
}

}  // namespace deep_ois
