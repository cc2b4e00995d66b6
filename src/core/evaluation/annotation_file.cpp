#include "deep_ois/core/evaluation/annotation_file.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace deep_ois {
namespace {

const char* const kHeader = "stamp_a,stamp_b,x_a,y_a,x_b,y_b,category";

std::string trim(const std::string& text) {
  const std::size_t first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(" \t") - first + 1);
}

std::vector<std::string> splitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(trim(field));
  if (!line.empty() && line.back() == ',')
    fields.push_back("");  // getline drops a trailing empty field
  return fields;
}

bool parseCoordinate(const std::string& text, double& value) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return errno == 0 && end == text.c_str() + text.size() && std::isfinite(value);
}

}  // namespace

std::size_t AnnotationFile::pointCount() const {
  std::size_t points = 0;
  for (const AnnotatedPair& pair : pairs) points += pair.points_a_px.size();
  return points;
}

bool parseStampNs(const std::string& text, std::int64_t& stamp_ns) {
  const std::size_t dot = text.find('.');
  const std::string whole = text.substr(0, dot);
  const std::string fraction = dot == std::string::npos ? "" : text.substr(dot + 1);
  // Digits only: no sign, exponent or spaces; at least one digit before the point; a point needs
  // digits after it.
  auto digits = [](const std::string& part) {
    return part.find_first_not_of("0123456789") == std::string::npos;
  };
  if (whole.empty() || !digits(whole) || !digits(fraction) || fraction.size() > 9) return false;
  if (dot != std::string::npos && fraction.empty()) return false;
  // A ROS stamp's seconds are uint32.
  if (whole.size() > 10 || std::stoull(whole) > std::numeric_limits<std::uint32_t>::max())
    return false;
  std::int64_t nanoseconds = 0;
  for (std::size_t i = 0; i < 9; ++i)
    nanoseconds = nanoseconds * 10 + (i < fraction.size() ? fraction[i] - '0' : 0);
  stamp_ns = static_cast<std::int64_t>(std::stoull(whole)) * 1000000000LL + nanoseconds;
  return true;
}

std::string formatStampNs(std::int64_t stamp_ns) {
  char text[32];
  std::snprintf(text, sizeof(text), "%lld.%09lld", static_cast<long long>(stamp_ns / 1000000000LL),
                static_cast<long long>(stamp_ns % 1000000000LL));
  return text;
}

AnnotationFile parseAnnotations(std::istream& in, const std::string& name) {
  AnnotationFile file;
  file.path = name;
  std::map<std::pair<std::int64_t, std::int64_t>, std::size_t> pair_index;
  std::string line;
  int line_number = 0;
  bool have_header = false;
  auto fail = [&](const std::string& problem) {
    throw std::runtime_error(name + ":" + std::to_string(line_number) + ": " + problem);
  };
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // UTF-8 BOM
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string content = trim(line);
    if (content.empty() || content[0] == '#') continue;
    if (!have_header) {
      if (content != kHeader)
        fail("expected the header '" + std::string(kHeader) + "', got '" + content + "'");
      have_header = true;
      continue;
    }
    const std::vector<std::string> fields = splitFields(content);
    if (fields.size() != 7) {
      fail("expected 7 comma-separated fields (" + std::string(kHeader) + "), got " +
           std::to_string(fields.size()));
    }
    std::int64_t stamp_a = 0, stamp_b = 0;
    if (!parseStampNs(fields[0], stamp_a))
      fail("stamp_a '" + fields[0] + "' is not seconds with up to 9 decimals");
    if (!parseStampNs(fields[1], stamp_b))
      fail("stamp_b '" + fields[1] + "' is not seconds with up to 9 decimals");
    if (stamp_b <= stamp_a)
      fail("stamp_b " + fields[1] + " is not later than stamp_a " + fields[0] +
           " (frame a is the earlier frame)");
    double xy[4];
    const char* names[4] = {"x_a", "y_a", "x_b", "y_b"};
    for (int k = 0; k < 4; ++k) {
      if (!parseCoordinate(fields[2 + k], xy[k]))
        fail(std::string(names[k]) + " '" + fields[2 + k] + "' is not a finite number");
    }
    const std::string& category = fields[6];
    if (category.empty()) fail("the category is empty");
    const auto key = std::make_pair(stamp_a, stamp_b);
    auto found = pair_index.find(key);
    if (found == pair_index.end()) {
      found = pair_index.emplace(key, file.pairs.size()).first;
      AnnotatedPair pair;
      pair.stamp_a_ns = stamp_a;
      pair.stamp_b_ns = stamp_b;
      pair.category = category;
      file.pairs.push_back(pair);
    }
    AnnotatedPair& pair = file.pairs[found->second];
    if (pair.category != category) {
      fail("category '" + category + "' differs from '" + pair.category +
           "' given for this pair on line " + std::to_string(pair.lines.front()));
    }
    pair.points_a_px.emplace_back(xy[0], xy[1]);
    pair.points_b_px.emplace_back(xy[2], xy[3]);
    pair.lines.push_back(line_number);
  }
  if (!have_header)
    throw std::runtime_error(name + ": no header line '" + std::string(kHeader) +
                             "' (empty file?)");
  if (file.pairs.empty()) throw std::runtime_error(name + ": no annotated point after the header");
  return file;
}

AnnotationFile readAnnotationFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the annotation file");
  return parseAnnotations(in, path);
}

}  // namespace deep_ois
