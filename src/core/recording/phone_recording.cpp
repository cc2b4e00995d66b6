#include "deep_ois/core/recording/phone_recording.h"

#include <cerrno>
#include <cmath>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace deep_ois {

namespace {

std::string formatMessage(const std::string& file, int line, const std::string& problem) {
  return line > 0 ? file + ":" + std::to_string(line) + ": " + problem : file + ": " + problem;
}

std::string trim(const std::string& text) {
  const char* blanks = " \t\r\n";
  const std::size_t first = text.find_first_not_of(blanks);
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(blanks) - first + 1);
}

// Parses a whole (trimmed) field as a finite double; `what` names the field in the error.
double parseNumber(const std::string& field, const std::string& what, const std::string& file,
                   int line) {
  const std::string text = trim(field);
  if (text.empty()) throw RecordingFormatError(file, line, what + " is empty");
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) {
    throw RecordingFormatError(file, line, what + " '" + text + "' is not a number");
  }
  if (errno == ERANGE || !std::isfinite(value)) {
    throw RecordingFormatError(file, line, what + " '" + text + "' is not a finite number");
  }
  return value;
}

std::string describeStamp(double stamp_s) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(6) << stamp_s << " s";
  return out.str();
}

void checkIncreasing(double stamp_s, double previous_s, int previous_line, const std::string& file,
                     int line) {
  if (previous_line > 0 && !(stamp_s > previous_s)) {
    throw RecordingFormatError(file, line,
                               "stamp " + describeStamp(stamp_s) + " does not increase (previous " +
                                   describeStamp(previous_s) + " on line " +
                                   std::to_string(previous_line) + ")");
  }
}

std::ifstream openOrThrow(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw RecordingFormatError(path, 0, "cannot open file for reading");
  return in;
}

}  // namespace

RecordingFormatError::RecordingFormatError(const std::string& file, int line,
                                           const std::string& problem)
    : std::runtime_error(formatMessage(file, line, problem)),
      file_(file),
      line_(line),
      problem_(problem) {}

std::vector<ImuSample> parseGyroCsv(std::istream& in, const std::string& source_name) {
  static const char* const kFieldNames[] = {"wx (rad/s)", "wy (rad/s)", "wz (rad/s)", "t (s)"};
  std::vector<ImuSample> samples;
  std::string text;
  int line = 0;
  int previous_line = 0;
  while (std::getline(in, text)) {
    ++line;
    if (trim(text).empty()) continue;
    std::vector<std::string> fields;
    std::stringstream row(text);
    std::string field;
    while (std::getline(row, field, ',')) fields.push_back(field);
    // getline drops an empty last field, so "a,b,c,d," would pass as four without this.
    if (!text.empty() && trim(text).back() == ',') fields.emplace_back();
    if (fields.size() != 4) {
      throw RecordingFormatError(
          source_name, line,
          "expected 4 comma-separated fields wx,wy,wz,t, got " + std::to_string(fields.size()));
    }
    ImuSample sample;
    for (int k = 0; k < 3; ++k) {
      sample.angular_velocity_rad_s[k] = parseNumber(fields[k], kFieldNames[k], source_name, line);
    }
    sample.stamp_s = parseNumber(fields[3], kFieldNames[3], source_name, line);
    if (!samples.empty()) {
      checkIncreasing(sample.stamp_s, samples.back().stamp_s, previous_line, source_name, line);
    }
    samples.push_back(sample);
    previous_line = line;
  }
  if (in.bad()) throw RecordingFormatError(source_name, line + 1, "read error");
  if (samples.empty()) throw RecordingFormatError(source_name, 0, "no gyro samples");
  return samples;
}

std::vector<ImuSample> loadGyroCsv(const std::string& path) {
  std::ifstream in = openOrThrow(path);
  return parseGyroCsv(in, path);
}

std::vector<LensShiftLogSample> parseLensShiftCsv(std::istream& in, const std::string& source_name,
                                                  std::vector<int>* lines) {
  static const char* const kFieldNames[] = {"t (s)", "x", "y", "cxx", "cxy", "cyy"};
  std::vector<LensShiftLogSample> samples;
  std::string text;
  int line = 0;
  int previous_line = 0;
  while (std::getline(in, text)) {
    ++line;
    const std::string trimmed = trim(text);
    if (trimmed.empty() || trimmed.front() == '#') continue;
    if (samples.empty() && previous_line == 0 && std::isalpha(static_cast<unsigned char>(trimmed.front()))) {
      previous_line = -1;  // the header; only one
      continue;
    }
    std::vector<std::string> fields;
    std::stringstream row(text);
    std::string field;
    while (std::getline(row, field, ',')) fields.push_back(field);
    if (trimmed.back() == ',') fields.emplace_back();
    if (fields.size() != 3 && fields.size() != 6) {
      throw RecordingFormatError(source_name, line,
                                 "expected 3 comma-separated fields t,x,y (or 6 with the covariance "
                                 "cxx,cxy,cyy), got " + std::to_string(fields.size()));
    }
    double values[6] = {0, 0, 0, 0, 0, 0};
    for (std::size_t k = 0; k < fields.size(); ++k) values[k] = parseNumber(fields[k], kFieldNames[k], source_name, line);
    LensShiftLogSample sample;
    sample.stamp_s = values[0];
    sample.logged = Eigen::Vector2d(values[1], values[2]);
    if (fields.size() == 6) sample.covariance = (Eigen::Matrix2d() << values[3], values[4], values[4], values[5]).finished();
    // Order is not checked here: a phone's log repeats samples out of order (repairLensShiftLog).
    samples.push_back(sample);
    if (lines) lines->push_back(line);
    previous_line = line;
  }
  if (in.bad()) throw RecordingFormatError(source_name, line + 1, "read error");
  if (samples.empty()) throw RecordingFormatError(source_name, 0, "no lens-shift samples");
  return samples;
}

std::vector<LensShiftLogSample> loadLensShiftCsv(const std::string& path, std::vector<int>* lines) {
  std::ifstream in = openOrThrow(path);
  return parseLensShiftCsv(in, path, lines);
}

std::vector<double> parseFrameStamps(std::istream& in, const std::string& source_name) {
  std::vector<double> stamps;
  std::string text;
  int line = 0;
  int previous_line = 0;
  int first_blank_line = 0;
  while (std::getline(in, text)) {
    ++line;
    if (trim(text).empty()) {
      if (first_blank_line == 0) first_blank_line = line;
      continue;
    }
    // The line index is the frame index, so a blank line inside the list would shift frames.
    if (first_blank_line > 0) {
      throw RecordingFormatError(source_name, first_blank_line,
                                 "blank line inside the frame stamp list (only allowed at the "
                                 "end, since line i is frame i)");
    }
    const double stamp = parseNumber(text, "frame stamp (s)", source_name, line);
    if (!stamps.empty()) checkIncreasing(stamp, stamps.back(), previous_line, source_name, line);
    stamps.push_back(stamp);
    previous_line = line;
  }
  if (in.bad()) throw RecordingFormatError(source_name, line + 1, "read error");
  if (stamps.empty()) throw RecordingFormatError(source_name, 0, "no frame stamps");
  return stamps;
}

std::vector<double> loadFrameStamps(const std::string& path) {
  std::ifstream in = openOrThrow(path);
  return parseFrameStamps(in, path);
}

std::vector<FrameImageFile> listFrameImages(const std::string& directory) {
  namespace fs = std::filesystem;
  static const char* const kImageExtensions[] = {".jpg", ".jpeg", ".png", ".bmp",
                                                 ".pgm", ".ppm",  ".tif", ".tiff"};
  std::error_code error;
  if (!fs::is_directory(directory, error)) {
    throw RecordingFormatError(directory, 0, "not a folder (expected the frame images)");
  }
  std::map<int, std::string> by_index;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory, error)) {
    if (!entry.is_regular_file()) continue;
    std::string extension = entry.path().extension().string();
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    bool is_image = false;
    for (const char* known : kImageExtensions) is_image = is_image || extension == known;
    if (!is_image) continue;
    const std::string stem = entry.path().stem().string();
    const std::string path = entry.path().string();
    std::size_t digits_start = stem.size();
    while (digits_start > 0 && std::isdigit(static_cast<unsigned char>(stem[digits_start - 1]))) {
      --digits_start;
    }
    const std::string digits = stem.substr(digits_start);
    if (digits.empty() || digits.size() > 9) {
      throw RecordingFormatError(path, 0,
                                 "the image name must end in its frame index (the 0-based line of "
                                 "the frame stamp list), e.g. frame-42.jpg");
    }
    const int index = std::stoi(digits);
    const auto [it, inserted] = by_index.emplace(index, path);
    if (!inserted) {
      throw RecordingFormatError(path, 0,
                                 "frame index " + std::to_string(index) + " is also the index of " +
                                     it->second);
    }
  }
  if (error) throw RecordingFormatError(directory, 0, "cannot list the folder: " + error.message());
  if (by_index.empty()) {
    throw RecordingFormatError(directory, 0, "no images (.jpg .jpeg .png .bmp .pgm .ppm .tif .tiff)");
  }
  std::vector<FrameImageFile> files;
  for (const auto& [index, path] : by_index) files.push_back({index, path});
  return files;
}

PhoneRecording loadPhoneRecording(const std::string& directory) {
  PhoneRecording recording;
  recording.gyro = loadGyroCsv(directory + "/gyro.txt");
  recording.frame_stamps_s = loadFrameStamps(directory + "/framestamp.txt");
  return recording;
}

}  // namespace deep_ois
