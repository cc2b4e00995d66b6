// Loader for phone recordings in the cc9pro layout (gyro CSV + frame stamp list). Pure C++: no ROS.
#pragma once

#include <istream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {

// A malformed or unreadable recording file. what() reads "<file>:<line>: <problem>" (no line
// part when the problem is the file as a whole), so it can be shown to the user as is.
class RecordingFormatError : public std::runtime_error {
 public:
  RecordingFormatError(const std::string& file, int line, const std::string& problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  // 1-based; 0 when the whole file is concerned
  const std::string& problem() const { return problem_; }

 private:
  std::string file_;
  int line_;
  std::string problem_;
};

// Gyro samples, rows `wx,wy,wz,t`: angular velocity in rad/s in the phone's IMU frame and the
// sample time in seconds. Stamps must be finite and strictly increasing; blank lines are skipped.
// `source_name` only labels error messages. Throws RecordingFormatError.
std::vector<ImuSample> parseGyroCsv(std::istream& in, const std::string& source_name);
std::vector<ImuSample> loadGyroCsv(const std::string& path);

// The camera's lens-shift log (docs/lens_shift_logs.md), rows `t,x,y` or `t,x,y,cxx,cxy,cyy`: the
// sample time in seconds on the frames' clock (Android: OisSample.getTimestampNanos() / 1e9, the
// SENSOR_TIMESTAMP clock), the shift as logged (OisSample.getXshift(), getYshift(): pixels of the
// active array) and optionally its covariance (logged units squared). A first line that starts
// with a letter is a header; blank lines and lines starting with '#' are skipped. Stamps must be
// finite; the samples are returned in file order (a phone's log repeats samples out of order:
// repairLensShiftLog in core/ois/lens_shift_log_repair.h sorts it), with their 1-based lines in
// `lines` when given. Throws RecordingFormatError.
std::vector<LensShiftLogSample> parseLensShiftCsv(std::istream& in, const std::string& source_name,
                                                  std::vector<int>* lines = nullptr);
std::vector<LensShiftLogSample> loadLensShiftCsv(const std::string& path, std::vector<int>* lines = nullptr);

// Frame stamps, one start-of-frame time in seconds per line; line i (0-based) is frame i, so blank
// lines are allowed only at the end. Stamps must be finite and strictly increasing. Throws
// RecordingFormatError.
std::vector<double> parseFrameStamps(std::istream& in, const std::string& source_name);
std::vector<double> loadFrameStamps(const std::string& path);

// One image of a recording's frame folder. The integer that ends the file name (before the
// extension) is the frame index, i.e. the 0-based line of the frame stamp list: RE_frame-99.jpg is
// frame 99.
struct FrameImageFile {
  int index = 0;
  std::string path;
};

// The images (.jpg .jpeg .png .bmp .pgm .ppm .tif .tiff, any case) of `directory`, sorted by frame
// index; other files are ignored. Throws RecordingFormatError for a missing folder, a folder
// without images, an image name that does not end in an index, or two images with one index.
std::vector<FrameImageFile> listFrameImages(const std::string& directory);

// A whole recording: gyro and frame stamps share one clock.
struct PhoneRecording {
  std::vector<ImuSample> gyro;
  std::vector<double> frame_stamps_s;
};

// Reads `<directory>/gyro.txt` and `<directory>/framestamp.txt`. Throws RecordingFormatError.
PhoneRecording loadPhoneRecording(const std::string& directory);

}  // namespace deep_ois
