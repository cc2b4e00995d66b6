// User-provided correspondences for scoring real recordings (no simulator truth): a CSV of point
// pairs per frame pair, read without ROS.
//
// The agreed format (also in the README, "Annotation files"):
//   CSV, UTF-8, '#' starts a comment line, first non-comment line is the header exactly:
//       stamp_a,stamp_b,x_a,y_a,x_b,y_b,category
//   One row per annotated point. stamp_a / stamp_b: the frames' header stamps in the bag, as
//   seconds with 9 decimals (e.g. 1594117812.123456789) - frame a is the earlier frame. x/y in
//   pixels of the raw (distorted) image, OpenCV convention ((0,0) = centre of the top-left pixel).
//   category: free text (e.g. RE/LT/LL/MF or "real"); all rows of one pair share it.
//   A pair is the set of rows with the same (stamp_a, stamp_b); 1 point per row; a pair needs >= 1
//   point. The evaluator matches a pair to the bag frames by exact stamps (to the nanosecond) and
//   fails with a clear message naming the file and line when a stamp is not a frame of the bag or a
//   line is malformed.
//
// Reading rules on top of the format: blank lines are skipped; a UTF-8 byte order mark and
// Windows line ends are accepted; a stamp may have 0 to 9 decimals (fewer are padded with zeros,
// more would not be a nanosecond stamp and are an error); fields may be padded with spaces; the
// category may not contain a comma (there is no quoting).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <istream>
#include <string>
#include <vector>

namespace deep_ois {

struct AnnotatedPair {
  std::int64_t stamp_a_ns = 0;  // header stamp of frame a, nanoseconds since the epoch
  std::int64_t stamp_b_ns = 0;  // frame b (later), nanoseconds since the epoch
  std::string category;
  std::vector<Eigen::Vector2d> points_a_px;  // raw pixels of frame a
  std::vector<Eigen::Vector2d> points_b_px;  // the same scene points in frame b
  std::vector<int> lines;                    // 1-based line of each point in the file
};

struct AnnotationFile {
  std::string path;
  std::vector<AnnotatedPair> pairs;  // in order of first appearance in the file
  std::size_t pointCount() const;
};

// Reads and checks a whole file. Throws std::runtime_error "PATH:LINE: problem" (or "PATH: problem"
// for a file that cannot be opened or holds no pair) on the first malformed line.
AnnotationFile readAnnotationFile(const std::string& path);
// The same from a stream; `name` stands for the file in messages.
AnnotationFile parseAnnotations(std::istream& in, const std::string& name);

// Parses "SECONDS[.FRACTION]" (up to 9 decimals) into nanoseconds; false when malformed.
bool parseStampNs(const std::string& text, std::int64_t& stamp_ns);
// Formats nanoseconds as the file writes them: seconds with 9 decimals.
std::string formatStampNs(std::int64_t stamp_ns);

}  // namespace deep_ois
